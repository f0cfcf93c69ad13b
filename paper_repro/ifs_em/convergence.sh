#!/usr/bin/env bash
# Convergence of EM fits on in-class data that ifslab did not generate (sample_ifs.py, Python's
# own generator): the share of seeds that converge (v_D >= 0.95) and that are right (coverage
# agreement with the generating code >= 0.9, see `fit-points --truth`), at the defaults of
# `ifslab fit-points DATA --k K --depth D --pool 10`, and with --paper (the paper's algorithm)
# on the K = 3 data sets.
# Usage: paper_repro/ifs_em/convergence.sh [REPEATS [PAPER_REPEATS]]   (default 16 and 8 seeds)
set -euo pipefail
cd "$(dirname "$0")"
ROOT=$(cd ../.. && pwd)
BIN=${IFSLAB:-$ROOT/target/release/ifslab}
REPEATS=${1:-16}
PAPER_REPEATS=${2:-8}
if [ ! -x "$BIN" ]; then
    (cd "$ROOT" && cargo build --release -p ifslab-experiments)
fi
OUT=results/convergence
DATA=$OUT/data
mkdir -p "$DATA"
TIMES=$OUT/timings.csv
echo "experiment,seconds" > "$TIMES"

sample() { # name, then sample_ifs.py arguments
    local name=$1
    shift
    python3 sample_ifs.py "$@" -o "$DATA/$name.csv" --code-out "$DATA/$name.json" 2> /dev/null
}

sweep() { # label, data name, then fit-points arguments
    local label=$1 name=$2 repeats=$3
    shift 3
    local t0=$SECONDS
    mkdir -p "$OUT/$label"
    "$BIN" fit-points "$DATA/$name.csv" --truth "$DATA/$name.json" --sweep-pool 10 \
        --repeats "$repeats" --seed 1 "$@" -o "$OUT/$label/$name" \
        2> >(grep -v '^\s*$' > "$OUT/$label/$name.log") || {
        echo "$label/$name failed, see $OUT/$label/$name.log" >&2
        exit 1
    }
    echo "$label/$name,$((SECONDS - t0))" >> "$TIMES"
    echo "$label/$name: $((SECONDS - t0)) s"
}

sample triangle-10k triangle -n 10000 --seed 1
sample triangle-1k triangle -n 1000 --seed 2
sample triangle-100k triangle -n 100000 --seed 3
sample triangle-frame triangle -n 10000 --seed 4 --scale 1000 --rotate 30 --shift 5e3,-2e3
sample triangle-uniform triangle -n 10000 --seed 5 --uniform
sample equilateral-10k equilateral -n 10000 --seed 6
sample pinwheel4 pinwheel4 -n 10000 --seed 7
sample spiral5 spiral5 -n 10000 --seed 8
sample random3 random --maps 3 --code-seed 1 -n 10000 --seed 9
sample random4 random --maps 4 --code-seed 2 -n 10000 --seed 10

# K and D per data set: D = 6 (5 for K = 5, as in Fig. 5a).
SETS="triangle-10k:3:6 triangle-1k:3:6 triangle-100k:3:6 triangle-frame:3:6 triangle-uniform:3:6
equilateral-10k:3:6 pinwheel4:4:6 spiral5:5:5 random3:3:6 random4:4:6"
for spec in $SETS; do
    IFS=: read -r name k d <<< "$spec"
    sweep defaults "$name" "$REPEATS" --k "$k" --depth "$d"
done
PAPER_SETS="triangle-10k:3:6 triangle-frame:3:6 equilateral-10k:3:6 random3:3:6"
for spec in $PAPER_SETS; do
    IFS=: read -r name k d <<< "$spec"
    sweep paper "$name" "$PAPER_REPEATS" --k "$k" --depth "$d" --paper
done
# Keep the committed folder small: the tables, not the charts or the sampled points.
find "$OUT" -name pool_sweep.png -delete
rm -f "$DATA"/*.csv
python3 summarise.py > /dev/null
echo "done; timings in $TIMES, table in results/summary.md"
