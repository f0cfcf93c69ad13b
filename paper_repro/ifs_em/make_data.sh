#!/usr/bin/env bash
# The point clouds of the convergence and ablation sweeps, written by sample_ifs.py (Python's
# own generator, not ifslab's chaos game) into data/sampled/: NAME.csv (points) and NAME.json
# (the generating code, the runs' `truth`). Deterministic; the CSVs are not committed.
#   paper_repro/ifs_em/make_data.sh
set -euo pipefail
cd "$(dirname "$0")"
out=data/sampled
mkdir -p "$out"
sample() { # name, then sample_ifs.py arguments
    local name=$1
    shift
    python3 sample_ifs.py "$@" -o "$out/$name.csv" --code-out "$out/$name.json" 2> /dev/null
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
sample square4 square4 -n 10000 --seed 11
sample carpet8 carpet8 -n 10000 --seed 12
echo "data in $(pwd)/$out"
