#!/usr/bin/env bash
# Rebuilds the flame test fixtures from flam3 3.1.1 (Debian packages flam3-utils,
# libflam3-dev, flam3-palette; installed here when missing and when apt-get is available).
#
#   scripts/flame_fixtures.sh variations   # tests/fixtures/flame/variations.json
#
# The fixtures are committed; the tests read them and need no flam3.
set -euo pipefail
cd "$(dirname "$0")/.."
dir=tests/fixtures/flame

need_flam3() {
  if ! pkg-config --exists flam3 2>/dev/null || ! command -v flam3-render >/dev/null; then
    if command -v apt-get >/dev/null && [ "$(id -u)" = 0 ]; then
      apt-get install -y -qq flam3-utils libflam3-dev flam3-palette >/dev/null
    else
      echo "flam3 is not installed (Debian: apt-get install flam3-utils libflam3-dev flam3-palette)" >&2
      exit 1
    fi
  fi
}

variations() {
  need_flam3
  local tmp
  tmp=$(mktemp -d)
  cc -O2 "$dir/record_variations.c" $(pkg-config --cflags --libs flam3 libxml-2.0) -lm \
    -o "$tmp/record_variations"
  "$tmp/record_variations" > "$dir/variations.json"
  rm -rf "$tmp"
  echo "wrote $dir/variations.json"
}

case "${1:-all}" in
  variations) variations ;;
  all) variations ;;
  *) echo "usage: $0 [variations|all]" >&2; exit 2 ;;
esac
