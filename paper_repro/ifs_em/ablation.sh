#!/usr/bin/env bash
# What each change of the EM defaults contributes: the defaults with one change undone at a
# time, and the M-step rules compared at the defaults, on the same seeds, on data that
# ifslab did not generate (sample_ifs.py; the same data sets and seeds as convergence.sh).
# Usage: paper_repro/ifs_em/ablation.sh [REPEATS]     (default 8 seeds per variant)
set -euo pipefail
cd "$(dirname "$0")"
ROOT=$(cd ../.. && pwd)
BIN=${IFSLAB:-$ROOT/target/release/ifslab}
REPEATS=${1:-8}
OUT=results/ablation
DATA=$OUT/data
mkdir -p "$DATA"

sample() { # name, then sample_ifs.py arguments
    local name=$1
    shift
    python3 sample_ifs.py "$@" -o "$DATA/$name.csv" --code-out "$DATA/$name.json" 2> /dev/null
}

variant() { # label, data name, then fit-points arguments
    local label=$1 name=$2
    shift 2
    local t0=$SECONDS
    mkdir -p "$OUT/$name"
    "$BIN" fit-points "$DATA/$name.csv" --truth "$DATA/$name.json" --sweep-pool 10 \
        --repeats "$REPEATS" --seed 1 "$@" -o "$OUT/$name/$label" 2> "$OUT/$name/$label.log" || {
        echo "$name/$label failed, see $OUT/$name/$label.log" >&2
        exit 1
    }
    echo "$name/$label: $(grep '^pool' "$OUT/$name/$label.log") ($((SECONDS - t0)) s)"
}

sample triangle-10k triangle -n 10000 --seed 1
sample equilateral-10k equilateral -n 10000 --seed 6
sample random4 random --maps 4 --code-seed 2 -n 10000 --seed 10

K3="--k 3 --depth 6"
variant defaults triangle-10k $K3
variant outermost triangle-10k $K3 --update outermost
variant fixed-depth triangle-10k $K3 --preselect-schedule fixed
variant by-mean-depth triangle-10k $K3 --preselect-by mean-depth
variant no-reorient triangle-10k $K3 --reorient 0
variant no-recentre triangle-10k $K3 --no-recentre
variant preselect-20 triangle-10k $K3 --preselect-iterations 20
variant paper-preselect triangle-10k $K3 --preselect-schedule fixed --preselect-by mean-depth
variant paper-preselect random4 --k 4 --depth 6 --preselect-schedule fixed --preselect-by mean-depth
variant defaults equilateral-10k $K3
variant outermost equilateral-10k $K3 --update outermost

find "$OUT" -name pool_sweep.png -delete
rm -f "$DATA"/*.csv
