#!/usr/bin/env bash
# The GPU checks, on a machine with an NVIDIA GPU, its driver and NVRTC (CUDA 13), from the
# repository root with gpu-bin/ built by scripts/gpu/build.sh. Writes everything it prints
# to OUT (default gpu-out/): the GPU, the tests' output, the benchmark.
#   scripts/gpu/run.sh [tests|bench|all]   (default all)
# BENCH: the criterion filter of the benchmark (default: the paper's and the demo's settings,
# CPU and GPU groups; e.g. BENCH='iteration_(paper|demo)_cuda' for the GPU groups alone).
set -uo pipefail
cd "$(dirname "$0")/../.."
what=${1:-all}
out=${OUT:-gpu-out}
mkdir -p "$out"
bin=gpu-bin
# NVRTC: the CUDA toolkit's, else a wheel's (nvidia-cuda-nvrtc) under a Python tree.
if ! ldconfig -p 2>/dev/null | grep -q 'libnvrtc.so.13'; then
  lib=$(find /usr/local/cuda/ /usr/local/cuda-13*/ /opt /usr/lib /usr/local/lib \
          -name 'libnvrtc.so.13' -print -quit 2>/dev/null)
  [ -n "$lib" ] && export LD_LIBRARY_PATH="$(dirname "$lib")${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
fi
status=0
{
  echo "== $(date -u +%FT%TZ) on $(hostname)"
  nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm --format=csv
  nvcc --version 2>/dev/null | tail -2
  echo "CPU: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2)"
  echo "LD_LIBRARY_PATH=${LD_LIBRARY_PATH:-}"
} 2>&1 | tee "$out/machine.txt"
if [ "$what" = all ] || [ "$what" = tests ]; then
  "$bin/splat_cuda" --test-threads 1 --nocapture 2>&1 | tee "$out/tests.log"
  [ "${PIPESTATUS[0]}" = 0 ] || status=1
  "$bin/image_inversion" --exact hybrid_recovers_the_sierpinski_triangle_on_the_gpu \
    --nocapture 2>&1 | tee -a "$out/tests.log"
  [ "${PIPESTATUS[0]}" = 0 ] || status=1
fi
if [ "$what" = all ] || [ "$what" = bench ]; then
  # The paper's setting (1024², 5×, σ 2.5, 480 k points) and the demo's, CPU and GPU groups.
  "$bin/splat" --bench "${BENCH:-iteration_(paper|demo)}" --warm-up-time 1 --measurement-time 3 \
    2>&1 | tee "$out/bench.log"
  [ "${PIPESTATUS[0]}" = 0 ] || status=1
fi
echo "== status $status" | tee -a "$out/machine.txt"
exit $status
