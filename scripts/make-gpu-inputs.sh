#!/usr/bin/env bash
# Prepares gpu_inputs/ (git-ignored) for scripts/gpu-check.sh on the lent GPU machine,
# which has no Debian packages and no network (/work/shared/reference/gpu-machine.md).
# The device tool carries at most 64 MiB with the working tree, and a compiled
# multi-million-triangle file does not fit, so the scenes travel as their sources and
# are compiled there, by a bundled cwbvhc:
#
#   gpu_inputs/cwbvhc-bundle.tar.xz   cwbvhc + every library it loads (scripts/bundle-cwbvhc.sh;
#                                     checked here by scripts/test-cwbvhc-bundle.sh)
#   gpu_inputs/scenes/NAME.EXT.xz     the GPU set's scene sources, xz-compressed
#   gpu_inputs/scenes/LIST            their order in the check (file names, one a line)
#   gpu_inputs/xxhash/xxhash.h        the one header the GPU-only build needs
#   gpu_inputs/optix/include/         the OptiX 9.0 headers, when OPTIX_INCLUDE_DIR names them
#
# The GPU set spans the paper's 80k-12.8M triangles: issue 10's five (bunny,
# sponza_dabrovic, oa_oacmpctf3, fg_cg57, dragon), dense_dragons (2.2M, DERIVED),
# dragon_loop1_draco (3.5M, DERIVED), kicad_board (3.9M, COMPOSITE) and the DERIVED
# composite derived_board_dragons (12.65M), which gpu-check.sh generates there with
# scripts/make-derived-composite.py from dragon, dragon_loop1_draco and kicad_board
# (so nothing of it travels but the generator). Scene stems are the view catalog's keys.
# The scenes that instance (kicad_board, dense_dragons, the composite) are compiled there a
# second time, two-level (issue 19): from the same sources, so nothing more travels.
# About 27 MiB in all (the bundle 11.4, the scenes 14.3, the OptiX headers 0.6); files are added in order while
# the total stays under CWBVH_GPU_INPUTS_MIB (default 56).
#
# usage: scripts/make-gpu-inputs.sh [SCENE...]   (default: the set above, from
#        $CWBVH_SHARED_SCENES or ../shared/scenes)
# env:   CWBVHC=path/to/cwbvhc to bundle (default build/bin/cwbvhc, built if missing)
#        OPTIX_INCLUDE_DIR=optix-dev v9.0.0's include/ (github.com/NVIDIA/optix-dev, tag
#        v9.0.0; never committed): copied to gpu_inputs/optix/include. Without it the
#        GPU check skips OptiX with one line.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out="$root/gpu_inputs"
scenes_dir=${CWBVH_SHARED_SCENES:-$root/../shared/scenes}
budget_mib=${CWBVH_GPU_INPUTS_MIB:-56}
cwbvhc=${CWBVHC:-$root/build/bin/cwbvhc}
if [[ $# -eq 0 ]]; then
  set -- bunny.glb sponza_dabrovic.glb oa_oacmpctf3.glb fg_cg57.glb dragon.glb dense_dragons.glb \
    dragon_loop1_draco.glb kicad_board.glb
fi
mkdir -p "$out/xxhash" "$out/scenes"
cp /usr/include/xxhash.h "$out/xxhash/xxhash.h"
# Compiled scenes of the earlier layout (NAME.cwbvh.xz) would be checked beside the
# compiled sources: drop them.
rm -f "$out"/*.cwbvh.xz "$out"/*.cwbvh

# OptiX headers (optional).
rm -rf "$out/optix"
if [[ -n "${OPTIX_INCLUDE_DIR:-}" ]]; then
  [[ -f "$OPTIX_INCLUDE_DIR/optix.h" && -f "$OPTIX_INCLUDE_DIR/optix_stubs.h" ]] ||
    { echo "make-gpu-inputs: OPTIX_INCLUDE_DIR=$OPTIX_INCLUDE_DIR has no optix.h/optix_stubs.h" >&2; exit 1; }
  mkdir -p "$out/optix"
  cp -r "$OPTIX_INCLUDE_DIR" "$out/optix/include"
  echo "optix/include: $(grep -m1 '^#define OPTIX_VERSION ' "$out/optix/include/optix.h" | awk '{print $3}') \
($(du -sk "$out/optix" | cut -f1) KiB)"
else
  echo "optix: OPTIX_INCLUDE_DIR not set: no OptiX headers travel (gpu-check.sh skips OptiX)"
fi

# The compiler bundle, rebuilt when cwbvhc is newer than it.
if [[ ! -x "$cwbvhc" ]]; then
  cmake -S "$root" -B "$root/build" -G Ninja >/dev/null
  ninja -C "$root/build" -j2 cwbvhc
fi
if [[ ! -f "$out/cwbvhc-bundle.tar.xz" || "$cwbvhc" -nt "$out/cwbvhc-bundle.tar.xz" ]]; then
  OUT="$out/cwbvhc-bundle.tar.xz" "$root/scripts/bundle-cwbvhc.sh" "$cwbvhc"
fi
total=$(du -sb "$out/xxhash" "$out/cwbvhc-bundle.tar.xz" | awk '{s += $1} END {print s}')
[[ -d "$out/optix" ]] && total=$((total + $(du -sb "$out/optix" | cut -f1)))

: > "$out/scenes/LIST.tmp"
for s in "$@"; do
  src="$scenes_dir/$s"
  [[ -f "$src" ]] || { echo "skip $s: not found in $scenes_dir" >&2; continue; }
  dst="$out/scenes/$s.xz"
  if [[ ! -f "$dst" || "$src" -nt "$dst" ]]; then
    xz -T2 -6 -c "$src" > "$dst.tmp"
    mv "$dst.tmp" "$dst"
  fi
  size=$(stat -c %s "$dst")
  if (( total + size > budget_mib * 1048576 )); then
    echo "drop $s: $((size >> 20)) MiB would exceed the ${budget_mib} MiB budget" >&2
    rm -f "$dst"
    continue
  fi
  total=$((total + size))
  echo "$s" >> "$out/scenes/LIST.tmp"
  echo "scenes/$s.xz: $((size >> 10)) KiB"
done
mv "$out/scenes/LIST.tmp" "$out/scenes/LIST"
# Sources no longer listed would still travel: remove them.
for f in "$out"/scenes/*.xz; do
  [[ -e "$f" ]] || continue
  grep -qxF "$(basename "${f%.xz}")" "$out/scenes/LIST" || rm -f "$f"
done
echo "gpu_inputs: $((total >> 10)) KiB in total ($(du -sb "$out" | awk '{printf "%.1f", $1 / 1048576}') MiB on disk)"
