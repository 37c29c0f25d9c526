#!/usr/bin/env bash
# The whole GPU check + benchmark in one call, for a GPU machine with only the CUDA
# toolkit, cmake and a C++ compiler (no Debian packages, no GoogleTest): configures a
# GPU-only build (format, loader, kernels, tools, cwbvh_gpu_check) against
# gpu_inputs/xxhash, saves ptxas -v for the device's arch, runs the check and the
# benchmark on every gpu_inputs/*.cwbvh (synthetic scene if none), prints the table
# last. Prepare gpu_inputs/ first with scripts/make-gpu-inputs.sh (on a machine with
# the compiler's dependencies; scenes travel as .cwbvh.xz and are unpacked here; with the
# device tool: carry ["gpu_inputs"]).
#
# Rays come from the view catalog (views/catalog.txt: every view of each scene, inside the
# enclosed ones; scene key = the .cwbvh file's stem), 2048x2048, primary + diffuse bounces 1-4.
#
# usage: scripts/gpu-check.sh [extra cwbvh_gpu_check args, e.g. --width 1024 --height 1024 --repeat 9]
# env:   BUILD=build-gpu  ARCH=(CMAKE_CUDA_ARCHITECTURES, default: the project's 75/90 set)
#        MIN_BLOCKS=N: the CWBVH kernel's __launch_bounds__ minimum blocks per SM (default 6 =
#        80 registers; 8 = 64): register/occupancy experiments, use a separate BUILD folder
#        CSV=path of the results table (default $BUILD/gpu_check.csv; commit a copy under
#        bench/results/gpu/ with the command and the device)
#        CWBVH_SANITIZE_GPU=0 skips the compute-sanitizer memcheck + racecheck pass (run last,
#        64x64 rays on the bunny or the synthetic scene; any report fails the check)
# exit:  0 only when cwbvh_gpu_check printed "RESULT: PASS". 1 a mismatch (or no PASS line);
#        2 a build, usage or CUDA error, or "SKIPPED" although nvidia-smi lists a GPU (the
#        kernels did not run where they should); 3 no GPU on this machine (nothing checked).
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
[[ -n "${MIN_BLOCKS:-}" ]] && arch_args+=(-DCWBVH_CWBVH_MIN_BLOCKS="$MIN_BLOCKS")
cmake -S "$root" -B "$build" "${gen[@]}" -DCMAKE_BUILD_TYPE=Release -DCWBVH_BUILD_COMPILER=OFF \
  -DCWBVH_BUILD_TESTS=OFF -DCWBVH_CUDA=ON -DCMAKE_CUDA_COMPILER="$nvcc" \
  -DCWBVH_XXHASH_INCLUDE_DIR="$xx" "${arch_args[@]}" > "$build.configure.log" 2>&1 ||
  { cat "$build.configure.log"; exit 2; }
cmake --build "$build" -j "$(nproc)" --target cwbvh_gpu_check cwbvh > "$build.build.log" 2>&1 ||
  { tail -40 "$build.build.log"; exit 2; }
tail -2 "$build.build.log"

# ptxas report for this device's architecture (compile only; next to the committed ones).
cc=$(nvidia-smi --query-gpu=compute_cap --format=csv,noheader 2>/dev/null | head -1 | tr -d . || true)
if [[ -n "$cc" ]]; then
  mkdir -p "$root/bench/results"
  cus=("$root"/kernels/src/kernels_*.cu)
  [[ -e "${cus[0]}" ]] || cus=("$root/kernels/src/trace.cu")
  "$root/scripts/ptxas-report.sh" "sm_$cc" "$root/bench/results/ptxas-sm_${cc}-device.txt" || true
  nvidia-smi --query-gpu=name,driver_version,clocks.max.sm,clocks.max.mem --format=csv || true
fi

# Scenes travel xz-compressed (make-gpu-inputs.sh): unpack each once, with xz or Python.
for z in "$inputs"/*.cwbvh.xz; do
  [[ -e "$z" ]] || continue
  [[ -f "${z%.xz}" && "${z%.xz}" -nt "$z" ]] && continue
  if command -v xz >/dev/null; then
    xz -dkc "$z" > "${z%.xz}.tmp"
  else
    python3 -c 'import lzma, shutil, sys; shutil.copyfileobj(lzma.open(sys.argv[1]), open(sys.argv[2], "wb"))' \
      "$z" "${z%.xz}.tmp"
  fi
  mv "${z%.xz}.tmp" "${z%.xz}"
done
scenes=("$inputs"/*.cwbvh)
[[ -e "${scenes[0]}" ]] || scenes=()
csv=${CSV:-$build/gpu_check.csv}
log="$build/gpu_check.log"
set +e
"$build/bin/cwbvh_gpu_check" --csv "$csv" "$@" "${scenes[@]}" 2>&1 | tee "$log"
rc=${PIPESTATUS[0]}
set -e
gpus=$(nvidia-smi -L 2>/dev/null | grep -c '^GPU ' || true)
if grep -q '^SKIPPED' "$log"; then
  if (( gpus > 0 )); then
    echo "gpu-check: FAIL: cwbvh_gpu_check skipped, but nvidia-smi lists $gpus GPU(s)" >&2
    exit 2
  fi
  echo "gpu-check: no GPU on this machine: nothing was checked" >&2
  exit 3
fi
if (( rc != 0 )); then
  echo "gpu-check: FAIL: cwbvh_gpu_check exited $rc" >&2
  exit "$rc"
fi
if ! grep -qx 'RESULT: PASS' "$log"; then
  echo "gpu-check: FAIL: no 'RESULT: PASS' line in the output" >&2
  exit 1
fi
# compute-sanitizer memcheck and racecheck on a small scene and a small image (issue
# 10: both must be clean); skipped with a note where the tool is not installed.
if [[ "${CWBVH_SANITIZE_GPU:-1}" == "1" ]]; then
  sanitizer=$(command -v compute-sanitizer || echo /usr/local/cuda/bin/compute-sanitizer)
  if [[ -x "$sanitizer" ]]; then
    small=()
    for s in "${scenes[@]}"; do
      [[ "$(basename "$s")" == bunny* ]] && small=("$s")
    done
    for tool in memcheck racecheck; do
      if ! "$sanitizer" --tool "$tool" --error-exitcode 9 "$build/bin/cwbvh_gpu_check" --width 64 --height 64 \
        --repeat 1 "${small[@]}" > "$build/sanitize-$tool.log" 2>&1; then
        tail -30 "$build/sanitize-$tool.log"
        echo "gpu-check: FAIL: compute-sanitizer $tool (log: $build/sanitize-$tool.log)" >&2
        exit 1
      fi
      grep -E "ERROR SUMMARY|RACECHECK SUMMARY" "$build/sanitize-$tool.log" | tail -1
    done
  else
    echo "gpu-check: compute-sanitizer not found: memcheck/racecheck not run" >&2
  fi
fi
echo "gpu-check: PASS (table: $csv)"
