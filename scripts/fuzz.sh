#!/usr/bin/env bash
# Longer fuzzing than CI's proptest cases: libFuzzer (cargo-fuzz, coverage-guided) on every
# input format, seeded with the repository's own files and the regression corpus.
#   scripts/fuzz.sh [SECONDS_PER_FORMAT] [FORMAT ...]      (default: 60, every format)
# Formats: code flame pattern config sweep csv npy image. Installs cargo-fuzz (crates.io)
# if missing; runs on stable Rust with --sanitizer none. Crashes land in
# fuzz/artifacts/FORMAT/; see fuzz/README.md for what to do with one.
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SECS="${1:-60}"
shift || true
FORMATS=("$@")
if [ ${#FORMATS[@]} -eq 0 ]; then FORMATS=(code flame pattern config sweep csv npy image); fi
command -v cargo-fuzz >/dev/null || cargo install cargo-fuzz --locked
cd "$REPO/fuzz"
seed() { # FORMAT GLOB...: copies the repository's files of a format into its corpus
  local fmt="$1"; shift
  mkdir -p "corpus/$fmt"
  cp "$REPO/experiments/tests/corpus/$fmt/"* "corpus/$fmt/" 2>/dev/null || true
  local n=0
  for f in "$@"; do
    [ -f "$f" ] || continue
    cp "$f" "corpus/$fmt/seed-$n-$(basename "$f")"
    n=$((n + 1))
    if [ $n -ge 40 ]; then break; fi
  done
  return 0
}
shopt -s nullglob globstar
seed code "$REPO"/paper_repro/**/code.json "$REPO"/experiments/codes/*.json
seed flame "$REPO"/paper_repro/**/*.flame "$REPO"/data/**/*.flame
seed pattern "$REPO"/paper_repro/**/*.pattern.json "$REPO"/data/**/*.pattern.json
seed config "$REPO"/experiments/configs/*.toml
seed sweep "$REPO"/paper_repro/**/sweeps/*.toml "$REPO"/experiments/sweeps/*.toml
seed csv "$REPO"/strategies/tests/data/*.csv
seed npy "$REPO"/data/**/*.npy
seed image "$REPO"/data/sdf/*.png
for fmt in "${FORMATS[@]}"; do
  echo "== $fmt: ${SECS} s" >&2
  # 4 GiB of RSS and 2 GiB per allocation at most: an input that asks for more is a bug.
  cargo fuzz run "$fmt" -s none -O "corpus/$fmt" -- \
    -max_total_time="$SECS" -rss_limit_mb=4096 -malloc_limit_mb=2048 -timeout=20 -max_len=65536
done
