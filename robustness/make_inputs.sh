#!/usr/bin/env bash
# Makes the inputs of the robustness suite with pinned NumPy and Pillow:
#   robustness/make_inputs.sh [--split tune|test|all] [-o OUTDIR] [--preview]
# Creates the virtual environment $REPO/target/robustness-venv (git-ignored) if missing,
# installs robustness/requirements.txt into it (again whenever that file changes), then runs
# make_inputs.py with the arguments given. Default output: robustness/inputs.
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
REPO="$(cd "$HERE/.." && pwd)"
VENV="$REPO/target/robustness-venv"
PY="${PYTHON:-python3}"
if [ ! -x "$VENV/bin/python" ]; then
  echo "creating $VENV" >&2
  mkdir -p "$REPO/target"
  "$PY" -m venv "$VENV"
fi
STAMP="$VENV/.robustness-requirements"
if ! cmp -s "$HERE/requirements.txt" "$STAMP"; then
  "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check -r "$HERE/requirements.txt"
  cp "$HERE/requirements.txt" "$STAMP"
fi
exec "$VENV/bin/python" "$HERE/make_inputs.py" "$@"
