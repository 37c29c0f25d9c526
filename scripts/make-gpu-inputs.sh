#!/usr/bin/env bash
# Prepares gpu_inputs/ (git-ignored) for scripts/gpu-check.sh on a GPU machine that
# has no Debian packages: compiled scenes (.cwbvh with the BVH2 section for the
# baseline) and the xxhash header. Rays and CPU reference hits are generated in
# process by cwbvh_gpu_check (same code on both machines), so no ray files travel.
# Budget: the device tool carries at most 64 MiB with the working tree, so scenes travel
# xz-compressed (NAME.cwbvh.xz, about 4x smaller; gpu-check.sh unpacks them there) and are
# added in order while the total stays under CWBVH_GPU_INPUTS_MIB (default 56). The
# default set is issue 10's target scenes: 26 MiB compressed (the dragon alone is 19).
# gpu_inputs/ is git-ignored: name it in the device tool's `carry`.
#
# usage: scripts/make-gpu-inputs.sh [SCENE...]   (default, in order of priority: bunny.obj
#        sponza_dabrovic.glb oa_oacmpctf3.glb fg_cg57.glb dragon.glb from
#        $CWBVH_SHARED_SCENES or ../shared/scenes; the file stem is the view catalog's
#        scene key, so keep the names)
# env:   CWBVHC=path/to/cwbvhc (default: build it in build/ with the full configuration)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out="$root/gpu_inputs"
scenes_dir=${CWBVH_SHARED_SCENES:-$root/../shared/scenes}
budget_mib=${CWBVH_GPU_INPUTS_MIB:-56}
cwbvhc=${CWBVHC:-$root/build/bin/cwbvhc}
if [[ ! -x "$cwbvhc" ]]; then
  cmake -S "$root" -B "$root/build" -G Ninja >/dev/null
  ninja -C "$root/build" -j2 cwbvhc
fi
if [[ $# -eq 0 ]]; then
  set -- bunny.obj sponza_dabrovic.glb oa_oacmpctf3.glb fg_cg57.glb dragon.glb
fi
mkdir -p "$out/xxhash"
cp /usr/include/xxhash.h "$out/xxhash/xxhash.h"
total=$(du -sb "$out/xxhash" | cut -f1)
for s in "$@"; do
  src="$scenes_dir/$s"
  [[ -f "$src" ]] || { echo "skip $s: not found in $scenes_dir" >&2; continue; }
  dst="$out/${s%.*}.cwbvh.xz"
  if [[ ! -f "$dst" ]]; then
    "$cwbvhc" "$src" -o "$out/${s%.*}.cwbvh" --keep-sbvh --quiet --threads 2
    xz -T2 -6 -f "$out/${s%.*}.cwbvh"  # replaces NAME.cwbvh by NAME.cwbvh.xz
  fi
  size=$(stat -c %s "$dst")
  if (( total + size > budget_mib * 1048576 )); then
    echo "drop $s: $((size >> 20)) MiB would exceed the ${budget_mib} MiB budget" >&2
    rm -f "$dst"
    continue
  fi
  total=$((total + size))
  echo "$(basename "$dst"): $((size >> 10)) KiB"
done
echo "gpu_inputs: $((total >> 10)) KiB in total"
