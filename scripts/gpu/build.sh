#!/usr/bin/env bash
# Builds what the GPU checks run, here on the development machine (x86-64; the GPU machine
# has the driver, CUDA and NVRTC but no Rust), into gpu-bin/ (git-ignored): the GPU test
# executables and the splat benchmark, all with `--features cuda`,
# release-optimised and without debug info (profile `gpu`). Then copy or carry the
# repository with gpu-bin/ to the GPU machine and run scripts/gpu/run.sh there (docs/GPU.md).
set -euo pipefail
cd "$(dirname "$0")/../.."
out=gpu-bin
rm -rf "$out"
mkdir -p "$out"
# Copies every executable cargo reports for `cargo ARGS` into gpu-bin/, named by target.
copy() {
  cargo "$@" --profile gpu --message-format json-render-diagnostics \
    | python3 -c '
import json, shutil, sys
for line in sys.stdin:
    m = json.loads(line)
    if m.get("reason") == "compiler-artifact" and m.get("executable"):
        shutil.copy(m["executable"], sys.argv[1] + "/" + m["target"]["name"])
        print("  " + m["target"]["name"])
' "$out"
}
echo "building into $out/:"
copy test -p ifslab --features cuda --test splat_cuda --no-run
copy test -p ifslab-strategies --features cuda --test image_inversion --no-run
copy bench -p ifslab --features cuda --bench splat --no-run

du -sh "$out"/*
