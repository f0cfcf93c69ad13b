#!/usr/bin/env bash
# How far our render of a flame is from flam3's, measured against how far flam3's renders of
# it from different seeds are from each other. Renders FILE.flame N times with flam3-render
# (one thread, isaac seeds 41..) and N times with `ifslab flame render` (seeds 21..), then
# prints the SSIM of the grey images (`ifslab flame compare`) over three sets of pairs:
# flam3 against flam3, ours against ours, ours against flam3. Where the third matches the
# first, what is left between the two renderers is sampling noise.
#   scripts/flame_seed_spread.sh FILE.flame [N]          (N = 6; needs flam3-render)
# One pair of renders is a poor judge: at the image fixtures' quality the SSIM of a single
# pair of flam3's own renders spreads by about 0.01 (standard deviation) on sparse pictures.
set -euo pipefail
file=$1
n=${2:-6}
root=$(cd "$(dirname "$0")/.." && pwd)
bin=${IFSLAB:-$root/target/release/ifslab}
[ -x "$bin" ] || bin=ifslab
command -v flam3-render >/dev/null || { echo "flam3-render is missing (apt-get install flam3-utils)" >&2; exit 1; }
[ -f "$file" ] || { echo "$file: no such file" >&2; exit 1; }
flames=$(grep -o '<flame[ >]' "$file" | wc -l)
[ "$flames" -eq 1 ] || { echo "$file holds $flames flames; give a file with one" >&2; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for s in $(seq 1 "$n"); do
    env in="$file" out="$tmp/flam3_$s.png" nthreads=1 isaac_seed=$((s + 40)) verbose=0 \
        flam3-render >/dev/null 2>&1
    "$bin" flame render "$file" -o "$tmp/ours_$s.png" --seed $((s + 20)) >/dev/null 2>&1
done
ssim() { "$bin" flame compare "$1" "$2" | awk '{print $2}'; }
summary() { # label, then SSIMs on stdin
    awk -v label="$1" '{ s += $1; q += $1 * $1; if (NR == 1 || $1 < lo) lo = $1; if (NR == 1 || $1 > hi) hi = $1 }
        END { m = s / NR; sd = sqrt(q / NR - m * m); printf "%-12s %3d pairs  mean %.4f  sd %.4f  min %.4f  max %.4f\n", label, NR, m, sd, lo, hi }'
}
for a in $(seq 1 "$n"); do for b in $(seq $((a + 1)) "$n"); do ssim "$tmp/flam3_$a.png" "$tmp/flam3_$b.png"; done; done | summary "flam3-flam3"
for a in $(seq 1 "$n"); do for b in $(seq $((a + 1)) "$n"); do ssim "$tmp/ours_$a.png" "$tmp/ours_$b.png"; done; done | summary "ours-ours"
for a in $(seq 1 "$n"); do for b in $(seq 1 "$n"); do ssim "$tmp/ours_$a.png" "$tmp/flam3_$b.png"; done; done | summary "ours-flam3"
