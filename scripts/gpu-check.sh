#!/usr/bin/env bash
# The whole GPU check + benchmark in one call, for a GPU machine with only the CUDA
# toolkit, cmake, a C++ compiler and Python 3 (no Debian packages, no GoogleTest, no
# network): configures a GPU-only build (format, loader, kernels, tools,
# cwbvh_gpu_check, and the OptiX peer when gpu_inputs/optix/include has the headers)
# against gpu_inputs/xxhash, saves ptxas -v for the device's arch, compiles the scenes
# there, runs the check and the benchmark, prints the tables last. Prepare gpu_inputs/
# first with scripts/make-gpu-inputs.sh (on a machine with the compiler's dependencies;
# with the device tool: carry ["gpu_inputs"]).
#
# Scenes: the sources in gpu_inputs/scenes (NAME.glb.xz ..., in the order of
# gpu_inputs/scenes/LIST) are unpacked and compiled by the bundled cwbvhc
# (gpu_inputs/cwbvhc-bundle.tar.xz: its own loader and libraries, nothing of the host's)
# with --keep-sbvh at $COMPILE_THREADS threads (default: all cores); each compile's wall
# time is printed and shown in the scene table beside OptiX's GAS build. Where
# dragon.glb, dragon_loop1_draco.glb and kicad_board.glb are among them, the DERIVED
# composite derived_board_dragons (12.65M triangles) is generated first
# (scripts/make-derived-composite.py) and compiled and checked last. Compiled scenes of
# the earlier layout (gpu_inputs/NAME.cwbvh.xz) are still unpacked and checked.
#
# Two-level scenes (issue 19): a GLB whose glTF instances a mesh (one mesh named by
# several nodes: kicad_board, dense_dragons and the DERIVED composite of the GPU set) is
# compiled a second time without flags, which keeps the instancing (format 1.2,
# SCENES/instanced/NAME.cwbvh; its wall time is printed and goes to the compile times as
# "instanced:NAME"). cwbvh_gpu_check pairs it with the flattened file of the same stem:
# the two-level kernel traces the flattened file's rays, is checked against
# trace_two_level_cpu (closest hit bit for bit up to equal-t ties; any hit by hit/miss),
# its hits are compared with the flattened file's, and its speed is printed beside the
# flattened file's CWBVH kernel (geometric mean, target 0.8x).
#
# The inline query (cwbvh/kernels/query.h: intersect from a kernel of the caller's, one
# thread per ray) traces every ray set of the flattened files and of the two-level files as
# well: checked against the CPU references the same way, its Mrays/s printed beside the
# batch CWBVH kernel's and the two-level kernel's.
#
# Rays come from the view catalog (views/catalog.txt: every view of each scene, inside the
# enclosed ones; scene key = the .cwbvh file's stem), 2048x2048, primary + diffuse bounces 1-4.
# Ray sets of fewer than 1M rays are printed but kept out of the geometric means.
# Time on the 16-core GPU machine, all nine scenes: about 6 minutes expected (build, compile,
# CPU reference, --repeat 3 on the five kernels (CWBVH, its two A/Bs, BVH2, OptiX) and the
# postponing sweep, sanitizer; estimated from the CPU side
# here, bench/README.md, "GPU: the three-way benchmark"): every scene keeps 2048x2048.
#
# usage: scripts/gpu-check.sh [extra cwbvh_gpu_check args, e.g. --width 1024 --height 1024 --repeat 9]
# env:   BUILD=build-gpu  ARCH=(CMAKE_CUDA_ARCHITECTURES, default: the project's 75/90 set)
#        MIN_BLOCKS=N: the CWBVH kernel's __launch_bounds__ minimum blocks per SM (default 6 =
#        80 registers; 8 = 64): register/occupancy experiments, use a separate BUILD folder
#        CSV=path of the results table (default $BUILD/gpu_check.csv; commit a copy under
#        bench/results/gpu/ with the command and the device)
#        COMPILE_THREADS=N cwbvhc threads (default: nproc)
#        POSTPONE_SWEEP=10,35,50 (default): cwbvh_gpu_check --postpone-sweep, the CWBVH kernel
#        (closest hit) also timed at these triangle postponing thresholds, percent of active
#        lanes (the default threshold is the paper's 20); empty: no sweep
#        CWBVHC_ARGS="..." extra cwbvhc options for every scene, flattened and two-level (a
#        tree experiment judged by GPU time over all views, e.g. "--collapse-cost-prim 0.6";
#        use a separate BUILD folder so that the default files stay)
#        TWO_LEVEL=auto (default: every GLB that instances a mesh) | none | "NAME ..." (scene
#        stems, e.g. "kicad_board dense_dragons"): the scenes also compiled two-level
#        DRY_RUN=1: build nothing and run no check; unpack the bundle and the scenes and
#        compile them (flattened and two-level) as the check would, print the compile
#        lines and the compile times, then exit 0 (runs without a GPU)
#        OPTIX_INCLUDE_DIR=OptiX 9.0 headers (default gpu_inputs/optix/include); none: OptiX
#        is skipped with one line (as it is where libnvoptix is missing)
#        DEADLINE_S=540 (default): seconds from this script's start by which the check must
#        have printed its tables (the device tool allows 600 a command): cwbvh_gpu_check
#        --deadline-s starts no view after DEADLINE_S less what the build and compiles used,
#        less 90 s (30 without the sanitizer; the first view always runs); the sanitizer is
#        skipped past DEADLINE_S - 60 and cut at DEADLINE_S + 50 (said in the last line, which
#        then reads "PASS ...; compute-sanitizer NOT run"); DEADLINE_S=0: no deadline
#        CWBVH_SANITIZE_GPU=0 skips the compute-sanitizer memcheck + racecheck pass (run last,
#        64x64 rays on the bunny or the synthetic scene, CWBVH and BVH2 kernels, and on
#        dense_dragons flattened + two-level where compiled: the two-level kernel; any
#        report fails the check)
# exit:  0 only when cwbvh_gpu_check printed "RESULT: PASS". 1 a mismatch (or no PASS line);
#        2 a build, usage, compile or CUDA error, or "SKIPPED" although nvidia-smi lists a GPU
#        (the kernels did not run where they should); 3 no GPU on this machine (nothing checked);
#        4 no mismatch, but the deadline (DEADLINE_S) stopped the check before every view ran
#        ("RESULT: PARTIAL"; the tables cover what ran).
set -euo pipefail
t_start=$(date +%s)
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
cc=$(nvidia-smi --query-gpu=compute_cap --format=csv,noheader 2>/dev/null | head -1 | tr -d . || true)
# The OptiX peer: on when the headers are there (its IR for this device's architecture).
optix_inc=${OPTIX_INCLUDE_DIR:-$inputs/optix/include}
if [[ -f "$optix_inc/optix.h" ]]; then
  arch_args+=(-DCWBVH_OPTIX_INCLUDE_DIR="$optix_inc" -DCWBVH_OPTIX_ARCH="${cc:-90}")
  targets=(cwbvh_gpu_check cwbvh cwbvh_optix_trace)
else  # cwbvh_gpu_check then says, in one line, that OptiX was skipped
  arch_args+=(-DCWBVH_OPTIX_INCLUDE_DIR=)
  targets=(cwbvh_gpu_check cwbvh)
fi
dry_run=${DRY_RUN:-0}
if [[ "$dry_run" == "1" ]]; then
  mkdir -p "$build"
  echo "gpu-check: DRY_RUN=1: no build, no check: the scene compiles only"
else
cmake -S "$root" -B "$build" "${gen[@]}" -DCMAKE_BUILD_TYPE=Release -DCWBVH_BUILD_COMPILER=OFF \
  -DCWBVH_BUILD_TESTS=OFF -DCWBVH_CUDA=ON -DCMAKE_CUDA_COMPILER="$nvcc" \
  -DCWBVH_XXHASH_INCLUDE_DIR="$xx" "${arch_args[@]}" > "$build.configure.log" 2>&1 ||
  { cat "$build.configure.log"; exit 2; }
cmake --build "$build" -j "$(nproc)" --target "${targets[@]}" > "$build.build.log" 2>&1 ||
  { tail -40 "$build.build.log"; exit 2; }
tail -2 "$build.build.log"
fi

# ptxas report for this device's architecture (compile only; next to the committed ones).
if [[ -n "$cc" && "$dry_run" != "1" ]]; then
  mkdir -p "$root/bench/results"
  cus=("$root"/kernels/src/kernels_*.cu)
  [[ -e "${cus[0]}" ]] || cus=("$root/kernels/src/trace.cu")
  "$root/scripts/ptxas-report.sh" "sm_$cc" "$root/bench/results/ptxas-sm_${cc}-device.txt" || true
  # SASS audit of the kernels as built (cuobjdump is in the GPU machine's toolkit): per kernel
  # instructions, local memory accesses, byte loads, byte rebuilds, cluster-slot reads.
  if [[ -f "$build/lib/libcwbvh_cuda.a" ]]; then
    "$root/bench/gpu/sass_audit.sh" "$build/lib/libcwbvh_cuda.a" > "$root/bench/results/sass-sm_${cc}-device.txt" 2>&1 &&
      sed -n '1,9p' "$root/bench/results/sass-sm_${cc}-device.txt" || echo "gpu-check: SASS audit skipped (no cuobjdump?)"
  fi
  nvidia-smi --query-gpu=name,driver_version,clocks.max.sm,clocks.max.mem --format=csv || true
fi

# Unpacks an .xz file with xz, or with Python where xz is missing.
unxz_to() {  # SRC.xz DST
  if command -v xz >/dev/null; then
    xz -dc "$1" > "$2.tmp"
  else
    python3 -c 'import lzma, shutil, sys; shutil.copyfileobj(lzma.open(sys.argv[1]), open(sys.argv[2], "wb"))' \
      "$1" "$2.tmp"
  fi
  mv "$2.tmp" "$2"
}

# Compiled scenes of the earlier layout (NAME.cwbvh.xz): unpack each once.
for z in "$inputs"/*.cwbvh.xz; do
  [[ -e "$z" ]] || continue
  [[ -f "${z%.xz}" && "${z%.xz}" -nt "$z" ]] && continue
  unxz_to "$z" "${z%.xz}"
done
scenes=()
for f in "$inputs"/*.cwbvh; do
  [[ -e "$f" ]] && scenes+=("$f")
done

# True when a GLB instances: a mesh named by several nodes, or a node placed under several
# parents (what cwbvhc keeps as instances by default; its stats JSON confirms it after).
instances_a_mesh() {  # FILE.glb
  [[ "$1" == *.glb ]] || return 1
  python3 - "$1" <<'PY'
import collections, json, struct, sys
with open(sys.argv[1], "rb") as f:
    head = f.read(20)
    if len(head) < 20 or head[:4] != b"glTF":
        sys.exit(1)
    n, kind = struct.unpack_from("<II", head, 12)
    if kind != 0x4E4F534A:  # JSON
        sys.exit(1)
    g = json.loads(f.read(n))
nodes = g.get("nodes", [])
meshes = collections.Counter(nd["mesh"] for nd in nodes if "mesh" in nd)
parents = collections.Counter(c for nd in nodes for c in nd.get("children", []))
sys.exit(0 if any(v > 1 for v in meshes.values()) or any(v > 1 for v in parents.values()) else 1)
PY
}

# Scene sources: unpack, generate the DERIVED composite, compile with the bundled cwbvhc.
times_file="$build/compile_times.txt"
: > "$times_file"
if [[ -f "$inputs/scenes/LIST" ]]; then
  work="$build/scenes"
  mkdir -p "$work"
  bundle="$build/cwbvhc-bundle"
  [[ -f "$inputs/cwbvhc-bundle.tar.xz" ]] ||
    { echo "gpu-check: FAIL: gpu_inputs/scenes without gpu_inputs/cwbvhc-bundle.tar.xz" >&2; exit 2; }
  if [[ ! -x "$bundle/cwbvhc" || "$inputs/cwbvhc-bundle.tar.xz" -nt "$bundle/cwbvhc" ]]; then
    rm -rf "$bundle"
    if command -v xz >/dev/null; then
      tar -C "$build" -xJf "$inputs/cwbvhc-bundle.tar.xz"
    else
      python3 -c 'import sys, tarfile; kw = {"filter": "tar"} if hasattr(tarfile, "tar_filter") else {}
tarfile.open(sys.argv[1], "r:xz").extractall(sys.argv[2], **kw)' \
        "$inputs/cwbvhc-bundle.tar.xz" "$build"
    fi
  fi
  head -1 "$bundle/MANIFEST"
  mapfile -t sources < "$inputs/scenes/LIST"
  for s in "${sources[@]}"; do
    [[ -f "$work/$s" && "$work/$s" -nt "$inputs/scenes/$s.xz" ]] || unxz_to "$inputs/scenes/$s.xz" "$work/$s"
  done
  if [[ -f "$work/dragon.glb" && -f "$work/dragon_loop1_draco.glb" && -f "$work/kicad_board.glb" ]]; then
    python3 "$root/scripts/make-derived-composite.py" "$work" "$work/derived_board_dragons.glb"
    sources+=(derived_board_dragons.glb)
  fi
  threads=${COMPILE_THREADS:-$(nproc)}
  read -r -a cwbvhc_args <<< "${CWBVHC_ARGS:-}"
  if (( ${#cwbvhc_args[@]} )); then echo "cwbvhc options for every scene (CWBVHC_ARGS): ${cwbvhc_args[*]}"; fi
  two_level=${TWO_LEVEL:-auto}
  rm -rf "$work/instanced"
  mkdir -p "$work/instanced"
  for s in "${sources[@]}"; do
    name=${s%.*}
    t0=$(date +%s.%N)
    if ! "$bundle/cwbvhc" "$work/$s" -o "$work/$name.cwbvh" --keep-sbvh --threads "$threads" --quiet "${cwbvhc_args[@]}" \
         --stats-json "$work/$name.stats.json" > "$work/$name.compile.log" 2>&1; then
      cat "$work/$name.compile.log"
      echo "gpu-check: FAIL: cwbvhc could not compile $s" >&2
      exit 2
    fi
    t1=$(date +%s.%N)
    secs=$(awk -v a="$t0" -v b="$t1" 'BEGIN {printf "%.2f", b - a}')
    echo "$name $secs" >> "$times_file"
    echo "compile $name: $secs s at $threads threads ($(( $(stat -c %s "$work/$name.cwbvh") >> 20 )) MiB)"
    scenes+=("$work/$name.cwbvh")
    # The two-level file of a scene that instances (no flags: cwbvhc keeps the instancing).
    case "$two_level" in
      none) continue ;;
      auto) instances_a_mesh "$work/$s" || continue ;;
      *) [[ " $two_level " == *" $name "* ]] || continue ;;
    esac
    inst="$work/instanced/$name.cwbvh"
    t0=$(date +%s.%N)
    if ! "$bundle/cwbvhc" "$work/$s" -o "$inst" --threads "$threads" --quiet "${cwbvhc_args[@]}" \
         --stats-json "$work/instanced/$name.stats.json" > "$work/instanced/$name.compile.log" 2>&1; then
      cat "$work/instanced/$name.compile.log"
      echo "gpu-check: FAIL: cwbvhc could not compile $s with its instancing" >&2
      exit 2
    fi
    t1=$(date +%s.%N)
    if ! grep -q '"two_level": true' "$work/instanced/$name.stats.json"; then
      echo "compile $name (two-level): cwbvhc kept no instancing: no two-level check for $name"
      rm -f "$inst"
      continue
    fi
    secs2=$(awk -v a="$t0" -v b="$t1" 'BEGIN {printf "%.2f", b - a}')
    echo "instanced:$name $secs2" >> "$times_file"
    echo "compile $name (two-level): $secs2 s at $threads threads ($(( $(stat -c %s "$inst") >> 10 )) KiB;" \
      "flattened: $secs s, $(( $(stat -c %s "$work/$name.cwbvh") >> 10 )) KiB)"
    scenes+=("$inst")
  done
fi
if [[ "$dry_run" == "1" ]]; then
  echo "gpu-check: DRY_RUN=1: compiled ${#scenes[@]} file(s); compile times ($times_file):"
  cat "$times_file"
  exit 0
fi
csv=${CSV:-$build/gpu_check.csv}
log="$build/gpu_check.log"
set +e
# The deadline: the check starts no view after DEADLINE_S seconds from this script's start,
# less a reserve for the sanitizer pass and the last view, so that a run under the device
# tool's 10-minute limit always ends with its tables.
deadline=${DEADLINE_S:-540}
deadline_args=()
if (( deadline > 0 )); then
  reserve=30
  [[ "${CWBVH_SANITIZE_GPU:-1}" == "1" ]] && reserve=90
  left=$(( deadline - ($(date +%s) - t_start) - reserve ))
  (( left < 30 )) && left=30
  deadline_args=(--deadline-s "$left")
  echo "gpu-check: $(( $(date +%s) - t_start )) s so far; the check starts no view after $left s more (DEADLINE_S=$deadline)"
fi
# The CWBVH kernel at other triangle postponing thresholds too (closest hit; the default is 20).
postpone=${POSTPONE_SWEEP-10,35,50}
sweep=()
[[ -n "$postpone" ]] && sweep=(--postpone-sweep "$postpone")
"$build/bin/cwbvh_gpu_check" --csv "$csv" --compile-times "$times_file" "${deadline_args[@]}" "${sweep[@]}" "$@" \
  "${scenes[@]}" 2>&1 | tee "$log"
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
partial=0
if (( rc == 4 )) && grep -qx 'RESULT: PARTIAL' "$log"; then
  partial=1  # no mismatch in what ran; the sanitizer still runs, the exit says partial
elif (( rc != 0 )); then
  echo "gpu-check: FAIL: cwbvh_gpu_check exited $rc" >&2
  exit "$rc"
elif ! grep -qx 'RESULT: PASS' "$log"; then
  echo "gpu-check: FAIL: no 'RESULT: PASS' line in the output" >&2
  exit 1
fi
# compute-sanitizer memcheck and racecheck on a small scene and a small image (issue
# 10: both must be clean); skipped with a note where the tool is not installed, or where
# less than a minute of DEADLINE_S is left; under a deadline each run is also cut at
# DEADLINE_S + 50 s (timeout), which counts as not run, not as clean.
sanitizer_skipped=""
if [[ "${CWBVH_SANITIZE_GPU:-1}" == "1" ]] && (( deadline > 0 && $(date +%s) - t_start > deadline - 60 )); then
  sanitizer_skipped="$(( $(date +%s) - t_start )) s used of DEADLINE_S=$deadline"
elif [[ "${CWBVH_SANITIZE_GPU:-1}" == "1" ]]; then
  sanitizer=$(command -v compute-sanitizer || echo /usr/local/cuda/bin/compute-sanitizer)
  if [[ -x "$sanitizer" ]]; then
    small=()
    for s in "${scenes[@]}"; do
      [[ "$(basename "$s")" == bunny* ]] && small+=("$s")
    done
    # The two-level kernel too: dense_dragons' two files (the smallest instanced pair).
    if [[ -f "$build/scenes/instanced/dense_dragons.cwbvh" ]]; then
      small+=("$build/scenes/dense_dragons.cwbvh" "$build/scenes/instanced/dense_dragons.cwbvh")
    fi
    for tool in memcheck racecheck; do
      limit=()
      if (( deadline > 0 )) && command -v timeout >/dev/null; then
        budget=$(( deadline + 50 - ($(date +%s) - t_start) ))
        if (( budget < 10 )); then
          sanitizer_skipped="$tool not started: the deadline (DEADLINE_S=$deadline)"
          break
        fi
        limit=(timeout "$budget")
      fi
      # --no-optix: the sanitizer checks our kernels, not OptiX's internals.
      set +e
      "${limit[@]}" "$sanitizer" --tool "$tool" --error-exitcode 9 "$build/bin/cwbvh_gpu_check" --width 64 \
        --height 64 --repeat 1 --no-optix "${small[@]}" > "$build/sanitize-$tool.log" 2>&1
      src=$?
      set -e
      if (( src == 124 && ${#limit[@]} )); then
        sanitizer_skipped="$tool cut by the deadline (DEADLINE_S=$deadline)"
        break
      elif (( src != 0 )); then
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
[[ -n "$sanitizer_skipped" ]] && echo "gpu-check: compute-sanitizer not run: $sanitizer_skipped" >&2
if (( partial )); then
  echo "gpu-check: PARTIAL: no mismatch, but the deadline stopped the check before every view ran (table: $csv)" >&2
  exit 4
fi
echo "gpu-check: PASS (table: $csv)${sanitizer_skipped:+; compute-sanitizer NOT run: $sanitizer_skipped}"
