#!/usr/bin/env bash
# Re-makes the results of paper_repro/ifs_em with the release binary:
#   Fig. 5a  fits of 2-D fractals (best of 8 runs by held-out likelihood, 300 iterations,
#            N' = 500, D = 6 (5 for K = 5), pool of 10), both M-step rules for the main ones;
#   Fig. 5b  proportion of converged runs against the pre-selection pool size (16 repeats);
#   3-D      IFS model against Gaussian mixtures on a Sierpinski tetrahedron and the CGAL
#            "kitten" point set.
# Usage: paper_repro/ifs_em/run.sh            (IFSLAB=/path/to/ifslab to use another binary)
set -euo pipefail
cd "$(dirname "$0")"
ROOT=$(cd ../.. && pwd)
BIN=${IFSLAB:-$ROOT/target/release/ifslab}
if [ ! -x "$BIN" ]; then
    (cd "$ROOT" && cargo build --release -p ifslab-experiments)
fi
OUT=results
mkdir -p "$OUT"
TIMES=$OUT/timings.csv
echo "experiment,seconds" > "$TIMES"

run() { # name, then fit-points arguments
    local name=$1
    shift
    local t0=$SECONDS
    mkdir -p "$(dirname "$OUT/$name")"
    "$BIN" fit-points "$@" 2> >(grep -v '^\s*$' > "$OUT/$name.log") || {
        echo "$name failed, see $OUT/$name.log" >&2
        exit 1
    }
    echo "$name,$((SECONDS - t0))" >> "$TIMES"
    echo "$name: $((SECONDS - t0)) s"
}

FIG5A="--runs 8 --iterations 300 --batch 500 --pool 10 --points 20000 --seed 1"
# Fig. 5a: the default (all-positions) M-step.
run fig5a/sierpinski-k3 ifs:sierpinski --k 3 --depth 6 $FIG5A -o $OUT/fig5a/sierpinski-k3
run fig5a/koch-k2 ifs:koch --k 2 --depth 6 $FIG5A -o $OUT/fig5a/koch-k2
run fig5a/koch-k4 ifs:koch --k 4 --depth 6 $FIG5A -o $OUT/fig5a/koch-k4
run fig5a/square-k4 ifs:configs/square.json --k 4 --depth 6 $FIG5A -o $OUT/fig5a/square-k4
run fig5a/dragon-k2 ifs:dragon --k 2 --depth 6 $FIG5A -o $OUT/fig5a/dragon-k2
run fig5a/levy-k2 ifs:levy --k 2 --depth 6 $FIG5A -o $OUT/fig5a/levy-k2
run fig5a/pentagon-k5 ifs:pentagon --k 5 --depth 5 $FIG5A -o $OUT/fig5a/pentagon-k5
run fig5a/fern-k4 ifs:fern --k 4 --depth 6 $FIG5A -o $OUT/fig5a/fern-k4
# The paper's own M-step rule (outermost map only) on the same data and seeds.
for spec in sierpinski-k3:sierpinski:3 koch-k2:koch:2 koch-k4:koch:4 square-k4:configs/square.json:4; do
    IFS=: read -r name src k <<< "$spec"
    run fig5a-outermost/$name ifs:$src --k $k --depth 6 --update outermost $FIG5A \
        -o $OUT/fig5a-outermost/$name
done

# Fig. 5b: proportion converged (v_D >= 0.95 after 300 iterations) per pool size, at the
# defaults with both M-step rules and with the paper's algorithm (same seeds).
SWEEP="--iterations 300 --batch 500 --depth 6 --points 20000 --seed 2 --sweep-pool 1,4,16 --repeats 16"
run fig5b-defaults/sierpinski-all-positions ifs:sierpinski --k 3 $SWEEP -o $OUT/fig5b-defaults/sierpinski-all-positions
run fig5b-defaults/sierpinski-outermost ifs:sierpinski --k 3 --update outermost $SWEEP -o $OUT/fig5b-defaults/sierpinski-outermost
run fig5b-defaults/sierpinski-paper ifs:sierpinski --k 3 --paper $SWEEP -o $OUT/fig5b-defaults/sierpinski-paper

# 3-D: IFS model against isotropic and full-covariance Gaussian mixtures (held-out nats/point).
run 3d/tetrahedron-k4 ifs:tetrahedron --k 4 --depth 5 --runs 8 --pool 10 --points 20000 --seed 3 \
    --gmm 4,8,16,32 -o $OUT/3d/tetrahedron-k4
run 3d/kitten-k4 data/kitten.csv --k 4 --depth 5 --runs 8 --pool 10 --seed 3 \
    --gmm 4,8,16,32 -o $OUT/3d/kitten-k4
run 3d/kitten-k3 data/kitten.csv --k 3 --depth 6 --runs 8 --pool 10 --seed 3 \
    --gmm 3,6,12,24 -o $OUT/3d/kitten-k3

# Keep the committed folder small: one log-likelihood curve and scatter per figure group.
find "$OUT" -name scatter.png ! -path '*fig5a/sierpinski-k3*' ! -path '*fig5a/koch-k4*' \
    ! -path '*3d/kitten-k4*' ! -path '*3d/tetrahedron*' -delete
find "$OUT" -name loglik.png ! -path '*fig5a/sierpinski-k3*' ! -path '*3d/kitten-k4*' -delete
python3 summarise.py > /dev/null
echo "done; timings in $TIMES, tables in $OUT/summary.md"
