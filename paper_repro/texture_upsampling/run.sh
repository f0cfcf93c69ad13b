#!/usr/bin/env bash
# Reproduces Kominami & Mukai's Table I, Fig. 4–6 and timing comparison on the project's
# textures (data/textures) with both presets (paper, ifslab), plus the one-choice-at-a-time
# table: writes tables.md, results.json and the figures into results/ (or --out DIR).
# About 17 minutes on 2 busy cores. Run from anywhere; extra arguments go to
# `ifslab texture repro` (e.g. --textures gravel --tables-only --skip-ablation --out /tmp/quick
# for a quick look, --timing-reps 21 for steadier timings, --resume to continue a killed run
# after the textures it finished).
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release -p ifslab-experiments
BIN="${CARGO_TARGET_DIR:-target}/release/ifslab"
"$BIN" texture repro "$@"
