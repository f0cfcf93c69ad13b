#!/usr/bin/env bash
# Time to an answer: whole-command wall times of the four inversion front-ends at their
# defaults (only the file and the map count, pattern or K given), on the robustness suite's
# test-split pictures and clouds, each command run N times in turn; prints min / median /
# max seconds. BENCHMARKS.md §8 quotes it.
#
#   scripts/time_to_answer.sh [N]          # N runs of each (default 3)
#   IFSLAB=target/ci/ifslab scripts/time_to_answer.sh
#   ONLY=invert scripts/time_to_answer.sh  # the commands whose name matches (grep -E)
#
# `invert`'s previous default (one run of 1000 iterations) is timed beside its default.
#
# The inputs are made by robustness/make_inputs.sh if they are missing (a venv in target/).
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${IFSLAB:-target/release/ifslab}
N=${1:-3}
IN=robustness/inputs/test
[ -x "$BIN" ] || cargo build --release -p ifslab-experiments
[ -f "$IN/manifest.json" ] || robustness/make_inputs.sh --split test \
  --families codes_random,patterns_koch,shapes,points3d
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT

# name | command (the output folder is appended)
commands=(
  "invert, 10 maps|$BIN invert $IN/codes_random/codes_random-00.jpg --maps 10"
  "invert, true N (3)|$BIN invert $IN/codes_random/codes_random-00.jpg --maps 3"
  "invert, 10 maps, one run of 1000|$BIN invert $IN/codes_random/codes_random-00.jpg --maps 10 --best-of 1 --iters 1000"
  "invert, true N (3), one run of 1000|$BIN invert $IN/codes_random/codes_random-00.jpg --maps 3 --best-of 1 --iters 1000"
  "sdf fit, Koch depth 5|$BIN sdf fit $IN/patterns_koch/patterns_koch-00.png --pattern koch --depth 5"
  "flame learn|$BIN flame learn $IN/shapes/shapes-00.png"
  "fit-points, 3-D, K 4|$BIN fit-points $IN/points3d/points3d-00.csv --k 4"
  "fit-points, 3-D, K 3|$BIN fit-points $IN/points3d/points3d-01.npy --k 3"
  "fit-points, 3-D, K 2|$BIN fit-points $IN/points3d/points3d-04.csv --k 2"
)
if [ -n "${ONLY:-}" ]; then
  kept=()
  for c in "${commands[@]}"; do
    if grep -Eq -- "$ONLY" <<< "${c%%|*}"; then kept+=("$c"); fi
  done
  commands=("${kept[@]}")
fi
declare -A times
for ((r = 0; r < N; r++)); do
  for i in "${!commands[@]}"; do
    cmd=${commands[$i]#*|}
    dir="$OUT/run-$i-$r"
    t0=$(date +%s.%N)
    $cmd -o "$dir" > /dev/null 2>&1 || { echo "failed: $cmd -o $dir" >&2; exit 1; }
    t1=$(date +%s.%N)
    times[$i]+="$(awk -v a="$t0" -v b="$t1" 'BEGIN { print b - a }') "
  done
done
printf '%-40s %8s %8s %8s  (%s runs, %s threads)\n' command min median max "$N" "$(nproc)"
for i in "${!commands[@]}"; do
  read -r -a v <<< "$(tr ' ' '\n' <<< "${times[$i]}" | grep . | sort -g | tr '\n' ' ')"
  printf '%-40s %8.1f %8.1f %8.1f\n' "${commands[$i]%%|*}" "${v[0]}" "${v[$(( ${#v[@]} / 2 ))]}" "${v[-1]}"
done
