#!/usr/bin/env bash
# Reproduces what paper_repro/differentiable_ifs/README.md reports for Scott's differentiable
# IFS: Fig. 2 (Koch, carpet, the horse silhouette, an apple and a flower drawn with
# tiny-skia; target | fit pictures and summaries), Fig. 3 (gradient fields at the Koch apex)
# and the local-optima measurement of Fig. 4 (Koch fits from jittered starts over seeds, with
# and without the self-crossing penalty; CSV + galleries), supplementary Fig. 5 (Koch on a
# filled square) and Fig. 7 (learned patterns). About 3 minutes of fits on 2 busy
# cores, after the build.
# Writes into results/ (or the folder given as the first argument).
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT="${1:-paper_repro/differentiable_ifs/results}"
# SKIP_BUILD=1 uses the binaries already built.
if [ -z "${SKIP_BUILD:-}" ]; then
  cargo build --profile ci -p ifslab-experiments --bin ifslab
  cargo build --profile ci -p ifslab-strategies --example sdf_seeds --example side_by_side \
    --example draw_silhouettes --example sdf_learned --example sdf_unit_square
  cargo build --profile ci -p ifslab-experiments --example sdf_gradient_field
fi
T="${CARGO_TARGET_DIR:-target}/ci"
BIN="$T/ifslab"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
mkdir -p "$OUT/fig2"

# Fig. 2. Targets drawn by the renderer (σ = 1 px) or given; every fit from the paper's
# best-fit-line start unless said.
"$BIN" sdf render koch --size 128 --depth 5 -o "$WORK/koch.png"
"$BIN" sdf render carpet --size 128 --depth 3 -o "$WORK/carpet.png"
"$T/examples/draw_silhouettes" "$WORK" 128   # apple.png, flower.png (tiny-skia)
fit() { # name target args…
  local name="$1" target="$2"
  shift 2
  "$BIN" sdf fit "$target" --paper -o "$WORK/$name" "$@" | tee -a "$OUT/fig2/fits.txt"
  cp "$WORK/$name/summary.json" "$OUT/fig2/$name.summary.json"
  cp "$WORK/$name/pattern.json" "$OUT/fig2/$name.pattern.json"
  "$T/examples/side_by_side" "$OUT/fig2/$name.png" "$WORK/$name/target.png" "$WORK/$name/render.png"
}
: > "$OUT/fig2/fits.txt"
fit koch "$WORK/koch.png" --pattern koch --depth 5 --sigma 1
fit carpet_line "$WORK/carpet.png" --pattern carpet --depth 3 --sigma 1
fit carpet "$WORK/carpet.png" --pattern carpet --depth 3 --sigma 1 --init pattern
fit horse "${SILHOUETTES:-../shared/data/silhouettes}/horse.png" --pattern carpet-square --depth 3 --sigma 1.5 \
  --sigma-start 6 --iterations 600
for s in apple flower; do
  fit "$s" "$WORK/$s.png" --pattern carpet-square --depth 3 --sigma 1.5 --sigma-start 6 --iterations 600
done

# Fig. 4: Koch at 64², depth 4, σ 1.5, 400 Adam steps, line start + Gaussian jitter, seeds
# 0–9; crossing weight 0 (the paper), 10 and 100 over the depth-1 copies, and 100 over the
# copies under words of length 3.
"$T/examples/sdf_seeds" --seeds 10 --jitters 0.03,0.06,0.1 --weights 0,10,100 \
  --gallery "$OUT/gallery" > "$OUT/koch_seeds_depth1.csv"
"$T/examples/sdf_seeds" --seeds 10 --jitters 0.06,0.1 --weights 100 --crossing-depth 3 \
  > "$OUT/koch_seeds_depth3.csv"

# Coarse to fine against the same local optima: σ from 6 px to 1.5 over the first 200 of the
# 400 steps.
"$T/examples/sdf_seeds" --seeds 10 --jitters 0.03,0.06,0.1 --weights 0 --sigma-start 6 \
  --sigma-iterations 200 --gallery "$OUT/gallery/coarse_to_fine" \
  > "$OUT/koch_seeds_coarse_to_fine.csv"

# Supplementary Fig. 5: the Koch pattern fitted to a filled square, seeds 0-7, without and
# with the barrier on the maps' scales.
"$T/examples/sdf_unit_square" --seeds 8 --gallery "$OUT/gallery/unit_square.png" \
  > "$OUT/unit_square.csv"
"$T/examples/sdf_unit_square" --seeds 8 --barrier 100 \
  --gallery "$OUT/gallery/unit_square_barrier100.png" > "$OUT/unit_square_barrier100.csv"

# Fig. 7: learned symmetry patterns on the same Koch target, seeds 0-4 (the last four
# settings with the scale barrier instead of refusing soft maps that expand).
"$T/examples/sdf_learned" --seeds 5 > "$OUT/learned_patterns.txt"

# Fig. 3: descent directions at p2 of the Koch curve (128², depth 5, σ 1.5) over 15×15
# positions, windows of half-side 0.15 (numbers only) and 0.3 (numbers and picture).
{
  "$T/examples/sdf_gradient_field" --half 0.15 "$WORK/fig3_gradient_field_0.15.png"
  "$T/examples/sdf_gradient_field" --half 0.3 "$OUT/fig3_gradient_field.png"
} | tee "$OUT/fig3.txt"
