#!/usr/bin/env bash
# Remakes docs/viewer.png, the README's picture of the zoom viewer (`ifslab serve`) on a run
# folder: a quick inversion of the built-in binary tree (its 128² render as the target,
# 4 maps, ifslab's default recipe cut to 300 iterations and one seed: about 15 s on two
# cores, IoU about 0.8) served with `ifslab serve` and opened in headless Chromium
# (scripts/viewer_lib.sh) at a fixed window (1000×720) and view: the target and the
# recovered code side by side, zoomed 2^0.3 (the target's pixels beside the code's tiles of
# level 1), in density mode with the inferno colours, and the run's loss curve beneath.
#
#   scripts/viewer_screenshot.sh [OUT.png]        # default docs/viewer.png
#
# Builds nothing: the binary is $IFSLAB, else target/release/ifslab. Chromium is installed
# from Debian's packages when absent (exit 77 where it cannot be).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-docs/viewer.png}
bin=${IFSLAB:-target/release/ifslab}
[ -x "$bin" ] || { echo "no ifslab binary at $bin: cargo build --release -p ifslab-experiments, or set IFSLAB"; exit 1; }
tmp=$(mktemp -d)
# shellcheck source=scripts/viewer_lib.sh
source scripts/viewer_lib.sh
trap viewer_cleanup EXIT
viewer_find_browser

# The run folder's name is the page's title ("run tree").
run="$tmp/tree"
echo "inverting the binary tree (300 iterations) into $run"
"$bin" invert tree --maps 4 --iters 300 --best-of 1 --seed 0 -o "$run" >"$tmp/invert.log" 2>&1 \
  || { echo "FAILED: ifslab invert"; tail -n 20 "$tmp/invert.log"; exit 1; }
tail -n 1 "$tmp/invert.log"

start_server "$run" --workers 2
page="${url}#level=0.3&x=0&y=0.04&mode=density&cmap=inferno"
echo "page: $page"
python3 "$tmp/shoot.py" "$browser" "$page" 1000x720 "$tmp/page.png" "$tmp/profile" \
  || { echo "FAILED: the browser"; tail -n 20 "$tmp/profile.log"; exit 1; }
stop_server
cp "$tmp/page.png" "$out"
echo "wrote $out"
