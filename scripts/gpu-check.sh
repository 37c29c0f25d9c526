#!/usr/bin/env bash
# The whole GPU check + benchmark in one call, for a GPU machine with only the CUDA
# toolkit, cmake and a C++ compiler (no Debian packages, no GoogleTest): configures a
# GPU-only build (format, loader, kernels, tools, cwbvh_gpu_check) against
# gpu_inputs/xxhash, saves ptxas -v for the device's arch, runs the check and the
# benchmark on every gpu_inputs/*.cwbvh (synthetic scene if none), prints the table
# last. Prepare gpu_inputs/ first with scripts/make-gpu-inputs.sh (on a machine with
# the compiler's dependencies).
#
# usage: scripts/gpu-check.sh [extra cwbvh_gpu_check args, e.g. --width 1920 --height 1080]
# env:   BUILD=build-gpu  ARCH=(CMAKE_CUDA_ARCHITECTURES, default: the project's 75/90 set)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${BUILD:-$root/build-gpu}
nvcc=${CUDACXX:-$(command -v nvcc || echo /usr/local/cuda/bin/nvcc)}
inputs="$root/gpu_inputs"
xx="$inputs/xxhash"
[[ -f "$xx/xxhash.h" ]] || xx=/usr/include   # fall back to a system header if present
gen=()
command -v ninja >/dev/null && gen=(-G Ninja)
arch_args=()
[[ -n "${ARCH:-}" ]] && arch_args=(-DCMAKE_CUDA_ARCHITECTURES="$ARCH")
cmake -S "$root" -B "$build" "${gen[@]}" -DCMAKE_BUILD_TYPE=Release -DCWBVH_BUILD_COMPILER=OFF \
  -DCWBVH_BUILD_TESTS=OFF -DCWBVH_CUDA=ON -DCMAKE_CUDA_COMPILER="$nvcc" \
  -DCWBVH_XXHASH_INCLUDE_DIR="$xx" "${arch_args[@]}" > "$build.configure.log" 2>&1 ||
  { cat "$build.configure.log"; exit 2; }
cmake --build "$build" -j "$(nproc)" --target cwbvh_gpu_check cwbvh 2>&1 | tail -3

# ptxas report for this device's architecture (compile only; next to the committed ones).
cc=$(nvidia-smi --query-gpu=compute_cap --format=csv,noheader 2>/dev/null | head -1 | tr -d . || true)
if [[ -n "$cc" ]]; then
  mkdir -p "$root/bench/results"
  "$nvcc" -std=c++17 -O3 -DNDEBUG -arch=sm_"$cc" -Xptxas -v -I"$root/kernels/include" -I"$root/format/include" \
    -I"$root/loader/include" -c "$root/kernels/src/trace.cu" -o "$build/ptxas_check.o" 2>&1 | c++filt \
    > "$root/bench/results/ptxas-sm_${cc}-device.txt" || true
  nvidia-smi --query-gpu=name,driver_version,clocks.max.sm,clocks.max.mem --format=csv || true
fi

scenes=("$inputs"/*.cwbvh)
[[ -e "${scenes[0]}" ]] || scenes=()
set +e
"$build/bin/cwbvh_gpu_check" "$@" "${scenes[@]}" 2>&1 | tee "$build/gpu_check.log"
rc=${PIPESTATUS[0]}
exit "$rc"
