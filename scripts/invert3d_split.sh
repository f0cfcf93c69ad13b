#!/usr/bin/env bash
# The multi-view inversion's splits, end to end (README, "In 3-D"): draws the views with the
# independent NumPy renderer (scripts/render3d_views.py), inverts each folder with each start
# asked for, and prints the table of voxel IoUs (the start's in brackets, c = the collage
# chosen, h = the hull's EM code).
#
#   scripts/invert3d_split.sh test OUT                     # both starts, seed 0
#   SEEDS="0 1" STARTS="collage" scripts/invert3d_split.sh tune OUT
#   SIZE=128 ARGS="--trajectories 1600" scripts/invert3d_split.sh test OUT
#
# OUT/views/<case>/ holds the views (drawn once), OUT/<start>-s<seed>/<case>/ each run; on
# the test split OUT/other/<case>/ holds 4 views at 55° elevation the fits never see, scored
# in each summary.json and drawn above the fit's renders in each run's other_views.png.
# IFSLAB names the binary (default target/release/ifslab, built if missing); the views need
# NumPy (target/robustness-venv, made by robustness/make_inputs.sh, or $PYTHON). Two runs go
# side by side on the machine's cores; each run's seconds are in its summary.json. SIZE is
# the views' side in pixels (default 64); ARGS are added to every `ifslab invert3d`.
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
split=${1:?usage: invert3d_split.sh tune|test OUT}
out=${2:?usage: invert3d_split.sh tune|test OUT}
SEEDS=${SEEDS:-0}
STARTS=${STARTS:-"collage hull"}
SIZE=${SIZE:-64}
read -r -a extra <<<"${ARGS:-}"
PY=${PYTHON:-$REPO/target/robustness-venv/bin/python}
[ -x "$PY" ] || PY=python3
BIN=${IFSLAB:-$REPO/target/release/ifslab}
[ -x "$BIN" ] || (cd "$REPO" && cargo build --release -p ifslab-experiments)
render="$PY $REPO/scripts/render3d_views.py"
case "$split" in
  # The fern's and the tetrahedron's tuning views are drawn apart from the test split's
  # (another azimuth and renderer seed); the random codes are other codes.
  tune) cases="random:11 random:12 random:13 random:14 random:15 random:16 random:17 random:18 fern tetrahedron" ;;
  test) cases="random:101 random:102 random:103 random:104 random:105 random:106 random:107 random:108 fern tetrahedron" ;;
  *) echo "the split is tune or test, not $split" >&2; exit 2 ;;
esac
mkdir -p "$out/views"
for c in $cases; do
  dir="$out/views/${c/:/}"
  if [ ! -f "$dir/truth.json" ]; then
    if [ "$split" = tune ] && { [ "$c" = fern ] || [ "$c" = tetrahedron ]; }; then
      $render "$c" "$dir" --size "$SIZE" --distance 2.6 --azimuth0 32.5 --seed 7 >/dev/null
    else
      $render "$c" "$dir" --size "$SIZE" --distance 2.6 >/dev/null
    fi
  fi
  if [ "$split" = test ] && [ ! -f "$out/other/${c/:/}/truth.json" ]; then
    $render "$c" "$out/other/${c/:/}" --size "$SIZE" --distance 2.6 --views 4 --elevation 55 --azimuth0 32.5 >/dev/null
  fi
done
jobs=0
for seed in $SEEDS; do
  for start in $STARTS; do
    for c in $cases; do
      name=${c/:/}
      run="$out/$start-s$seed/$name"
      [ -f "$run/summary.json" ] && continue
      rm -rf "$run"
      mkdir -p "$(dirname "$run")"
      other=()
      [ "$split" = test ] && other=(--score-views "$out/other/$name")
      "$BIN" invert3d "$out/views/$name" --maps 4 -o "$run" --truth "$out/views/$name/truth.json" \
        --seed "$seed" --start "$start" "${other[@]}" "${extra[@]}" >"$run.log" 2>&1 &
      jobs=$((jobs + 1))
      if [ $((jobs % 2)) = 0 ]; then wait; fi
    done
  done
done
wait
"$PY" - "$out" "$SEEDS" "$STARTS" $cases <<'PY'
import json, sys
out, seeds, starts, cases = sys.argv[1], sys.argv[2].split(), sys.argv[3].split(), sys.argv[4:]
cols = [(s, seed) for seed in seeds for s in starts]
print("| case | " + " | ".join(f"{s}, seed {seed}" for s, seed in cols) + " |")
print("|---|" + "---:|" * len(cols))
means = {c: [] for c in cols}
for case in cases:
    name = case.replace(":", "")
    row = []
    for s, seed in cols:
        summary = json.load(open(f"{out}/{s}-s{seed}/{name}/summary.json"))
        iou = summary["fit"]["voxel_iou"]
        if name.startswith("random"):
            means[(s, seed)].append(iou)
        choice = summary.get("start_choice")
        note = f" ({choice['chosen'][0]} {summary['start']['voxel_iou']:.2f})" if choice else ""
        row.append(f"{iou:.3f}{note}")
    print(f"| {name} | " + " | ".join(row) + " |")
print("| random codes, mean | " + " | ".join(f"{sum(v) / len(v):.3f}" for v in means.values()) + " |")
PY
