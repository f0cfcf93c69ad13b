#!/usr/bin/env bash
# Rebuilds the flame test fixtures from flam3 3.1.1 (Debian packages flam3-utils,
# libflam3-dev, flam3-palette; installed here when missing and when apt-get is available).
#
#   scripts/flame_fixtures.sh variations   # tests/fixtures/flame/variations.json
#   scripts/flame_fixtures.sh images       # tests/fixtures/flame/images/*.flame + flam3's PNGs
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

# Image fixtures: one flam3-genome random flame per variation (use_vars=N: every transform
# uses only that variation) and a few mixed ones (flam3-genome's default variation set),
# resized by a template to SIZE² at QUALITY, each rendered twice by flam3-render on one
# thread (flam3 is only reproducible single-threaded) with two seeds: NAME.png is the
# reference, NAME.again.png measures how far two correct renders differ by sampling noise
# alone. f00–f05 are m06 with camera, filter and tone-map settings changed. Seeds are
# fixed, so the files are the same on every run; existing files are kept unless FORCE=1.
SIZE=${SIZE:-128}
QUALITY=${QUALITY:-250}
MIXED=${MIXED:-8}
images() {
  need_flam3
  local out=$dir/images tmp
  mkdir -p "$out"
  tmp=$(mktemp -d)
  echo "<flame size=\"$SIZE $SIZE\" quality=\"$QUALITY\" supersample=\"1\"/>" > "$tmp/template.flame"
  genome() { # name seed use_vars (empty: flam3-genome's default set) [sed script]
    local name=$1 seed=$2
    if [ -n "${FORCE:-}" ] || [ ! -s "$out/$name.flame" ]; then
      env seed="$seed" isaac_seed="$seed" ${3:+use_vars=$3} template="$tmp/template.flame" \
        enclosed=0 noedits=1 flam3-genome 2>/dev/null | sed "${4:-}" > "$out/$name.flame"
    fi
    render2 "$name" "$seed"
  }
  derived() { # name seed base sed-script: another fixture with settings changed
    if [ -n "${FORCE:-}" ] || [ ! -s "$out/$1.flame" ]; then
      sed "$4" "$out/$3.flame" > "$out/$1.flame"
    fi
    render2 "$1" "$2"
  }
  render2() { # name seed
    local name=$1 seed=$2
    for pass in "$name.png $((seed + 7))" "$name.again.png $((seed + 100007))"; do
      set -- $pass
      if [ -n "${FORCE:-}" ] || [ ! -s "$out/$1" ]; then
        in="$out/$name.flame" out="$out/$1" nthreads=1 isaac_seed=$2 verbose=0 \
          flam3-render >/dev/null 2>&1
      fi
    done
  }
  for v in $(seq 0 98); do
    if [ "$v" = 67 ]; then
      # pre_blur only moves the input of the other variations: alone it draws nothing (and
      # flam3-genome crashes on it), so its flame is a linear one with pre_blur added.
      genome v67 1067 0 's/linear="1"/linear="1" pre_blur="0.25"/'
    else
      genome "$(printf v%02d "$v")" $((1000 + v)) "$v"
    fi
  done
  for m in $(seq 0 $((MIXED - 1))); do
    genome "$(printf m%02d "$m")" $((5000 + m)) ""
  done
  # Camera and tone-map settings flam3-genome leaves at their defaults, on mixed flame m06.
  derived f00 6000 m06 's/rotate="0"/rotate="30"/; s/background="0 0 0"/background="0.2 0.1 0.3"/'
  derived f01 6001 m06 's/vibrancy="1"/vibrancy="0.5"/; s/highlight_power="-1"/highlight_power="1"/; s/gamma_threshold="0.01"/gamma_threshold="0.1"/'
  derived f02 6002 m06 's/palette_mode="step"/palette_mode="linear"/; s/supersample="1"/supersample="2"/'
  derived f03 6003 m06 's/filter_shape="gaussian"/filter_shape="box"/; s/filter="0.5"/filter="1.2"/'
  derived f04 6004 m06 's/filter_shape="gaussian"/filter_shape="lanczos2"/; s/filter="0.5"/filter="1.2"/'
  derived f05 6005 m06 's/estimator_radius="9"/estimator_radius="0"/; s/brightness="4"/brightness="8"/; s/gamma="4"/gamma="2.5"/' 
  # Filters with negative lobes at the sampled points.
  derived f06 6006 m06 's/filter_shape="gaussian"/filter_shape="mitchell"/; s/filter="0.5"/filter="1.2"/'
  derived f07 6007 m06 's/filter_shape="gaussian"/filter_shape="lanczos3"/; s/filter="0.5"/filter="1.2"/'
  derived f08 6008 m06 's/filter_shape="gaussian"/filter_shape="hanning"/; s/filter="0.5"/filter="1.2"/'
  derived f09 6009 m06 's/filter_shape="gaussian"/filter_shape="hamming"/; s/filter="0.5"/filter="1.2"/'
  rm -rf "$tmp"
  echo "wrote $(ls "$out"/*.flame | wc -l) flames and their flam3 renders to $out"
}

case "${1:-all}" in
  variations) variations ;;
  images) images ;;
  all) variations; images ;;
  *) echo "usage: $0 [variations|images|all]" >&2; exit 2 ;;
esac
