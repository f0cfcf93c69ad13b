#!/usr/bin/env bash
# Reproduces what paper_repro/fractal_flames/README.md reports for Bannister &
# Nowrouzezahrai's learnable fractal flames: Fig. 4 (circles3, 8 generators, seven
# variations), Fig. 6 (20² and 3 generators), Fig. 1 (Fighting Forms, Wisteria), Fig. 5
# (50², 8 generators per flame) and Fig. 7 (Fighting Forms with other variations), each from
# its config in configs/, plus flam3-render's picture of the learned .flame files when
# flam3-render is installed. About 22 minutes on 2 cores after the build.
# Writes into results/ (or the folder given as the first argument).
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT="${1:-paper_repro/fractal_flames/results}"
if [ -z "${SKIP_BUILD:-}" ]; then
  cargo build --profile ci -p ifslab-experiments --bin ifslab
fi
BIN="${CARGO_TARGET_DIR:-target}/ci/ifslab"
mkdir -p "$OUT"
for cfg in paper_repro/fractal_flames/configs/*.toml; do
  name="$(basename "$cfg" .toml)"
  if [ -f "$OUT/$name/summary.json" ]; then continue; fi
  rm -rf "$OUT/$name"
  "$BIN" run "$cfg" -o "$OUT/$name"
  # Keep what people look at and what identifies the run; drop the resumable state and
  # the pictures compare.png already shows.
  rm -f "$OUT/$name/checkpoint.json" "$OUT/$name/start.json" "$OUT/$name/target.png" \
    "$OUT/$name/render.png"
done
# The pictures drawn from a finished run's files, where they are missing (the committed
# results keep none of them): the loss plot from log.csv, the learned .flame drawn by flam3's
# algorithm (our renderer; the layers of a stack composited), and by flam3-render itself for
# single flames when it is installed (flam3 has no layers: it would draw each flame of a
# stack on its own; its pictures differ from run to run by its sampling noise).
for cfg in paper_repro/fractal_flames/configs/*.toml; do
  dir="$OUT/$(basename "$cfg" .toml)"
  [ -f "$dir/loss.png" ] || "$BIN" redraw "$dir" >/dev/null
  [ -f "$dir/flame_render.png" ] || "$BIN" flame render "$dir/learned.flame" --composite \
    --quality 100 -o "$dir/flame_render.png" 2>/dev/null
  if [ ! -f "$dir/flam3.png" ] && command -v flam3-render >/dev/null 2>&1 \
    && [ "$(grep -c "<flame " "$dir/learned.flame")" = 1 ]; then
    (cd "$dir" && env in=learned.flame out=flam3.png nthreads=2 isaac_seed=1 \
      flam3-render >/dev/null 2>&1 || echo "flam3-render failed on $dir")
  fi
done
# One table of every run's numbers (from each summary.json).
field() { sed -n "s/^  \"$2\": \(.*\),\{0,1\}$/\1/p" "$1" | tr -d ',' | head -1; }
{
  echo "| run | iterations | MSE start | MSE end | ms/iteration | seconds |"
  echo "|---|---|---|---|---|---|"
  for s in "$OUT"/fig*/summary.json; do
    d="$(basename "$(dirname "$s")")"
    printf '| %s | %s | %.4f | %.4f | %.1f | %.1f |\n' "$d" "$(field "$s" iterations)" \
      "$(field "$s" start_mse)" "$(field "$s" mse)" \
      "$(echo "$(field "$s" seconds_per_iteration) * 1000" | bc -l)" "$(field "$s" seconds)"
  done
} > "$OUT/table.md"
cat "$OUT/table.md"
