#!/usr/bin/env bash
# Checks the cwbvhc bundle (scripts/bundle-cwbvhc.sh) here, as the GPU machine will
# start it: unpacked outside the repository and the build tree, run from another empty
# folder under `env -i` (no PATH, no LD_* variables), with LD_DEBUG=libs recording every
# library the loader opens. Passes when
#   1. every library the cwbvhc process loads (after the wrapper's /bin/sh hands over),
#      the loader and glibc included, comes from the bundle's lib/ (paths elsewhere are
#      only probed for optional libraries, and listed), and
#   2. the bundle compiles SCENE to a file byte-identical with the one the normally
#      built cwbvhc (build/bin/cwbvhc, the host's libraries) writes from the same
#      arguments.
# usage: scripts/test-cwbvhc-bundle.sh [SCENE]   (default: dense_dragons.glb of the shared scenes)
# env:   BUNDLE=the .tar.xz (default gpu_inputs/cwbvhc-bundle.tar.xz), CWBVHC=the reference binary
# exit:  0 pass, 1 fail
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bundle=${BUNDLE:-$root/gpu_inputs/cwbvhc-bundle.tar.xz}
ref=${CWBVHC:-$root/build/bin/cwbvhc}
scene=${1:-${CWBVH_SHARED_SCENES:-$root/../shared/scenes}/dense_dragons.glb}
scene=$(readlink -f "$scene")
[[ -f "$bundle" && -x "$ref" && -f "$scene" ]] || { echo "need $bundle, $ref and $scene" >&2; exit 1; }
t=$(mktemp -d /tmp/cwbvhc-bundle-test.XXXXXX)
trap 'rm -rf "$t"' EXIT
mkdir "$t/unpacked" "$t/run" "$t/debug"
tar -C "$t/unpacked" -xJf "$bundle"
lib="$t/unpacked/cwbvhc-bundle/lib/"
cd "$t/run"
env -i LD_DEBUG=libs LD_DEBUG_OUTPUT="$t/debug/ld" "$t/unpacked/cwbvhc-bundle/cwbvhc" "$scene" \
  -o "$t/bundle.cwbvh" --keep-sbvh --threads 2 --quiet
"$ref" "$scene" -o "$t/host.cwbvh" --keep-sbvh --threads 2 --quiet

fail=0
# The cwbvhc process: the debug file that initialises "cwbvhc"; its part after the
# wrapper's shell hands over (exec keeps the pid, so both write the same file).
log=$(grep -l "initialize program: cwbvhc" "$t"/debug/ld.* | head -1)
[[ -n "$log" ]] || { echo "FAIL: no LD_DEBUG record of the cwbvhc process" >&2; exit 1; }
after=$(awk '/transferring control: \/bin\/sh/ {on = 1; next} on' "$log")
loaded=$(grep -o 'calling init: .*' <<<"$after" | sed 's/calling init: //')
tried=$(grep -o 'trying file=[^ ]*' <<<"$after" | sed 's/trying file=//')
echo "libraries the cwbvhc process initialised (LD_DEBUG=libs):"
sed 's/^/  /' <<<"$loaded"
# Every library initialised must be the bundle's. Paths outside it are only probed for
# optional libraries oneTBB looks for and goes on without (libirml.so.1; libiomp5.so
# with RTLD_NOLOAD, which maps nothing even where it exists, as LLVM's libomp here).
outside=$(grep -v "^$lib" <<<"$loaded" | grep -v '^$' || true)
if [[ -n "$outside" ]]; then
  echo "FAIL: libraries initialised from outside the bundle:" >&2
  sed 's/^/  /' <<<"$outside" >&2
  fail=1
else
  echo "every library initialised is under the bundle's lib/ ($(wc -l <<<"$loaded") libraries)"
fi
optional=$(grep -v "^$lib" <<<"$tried" | grep -v '^$' | xargs -r -n1 basename | sort -u | tr '\n' ' ')
[[ -z "$optional" ]] || echo "probed outside the bundle, not loaded (optional): $optional"
if cmp -s "$t/bundle.cwbvh" "$t/host.cwbvh"; then
  echo "byte-identical: $(basename "$scene") -> $(stat -c %s "$t/bundle.cwbvh") bytes, sha256 $(sha256sum < "$t/bundle.cwbvh" | cut -c1-16)..."
else
  echo "FAIL: the bundle's $(basename "$scene") output differs from $ref's" >&2
  fail=1
fi
(( fail == 0 )) && echo "bundle test: PASS" || echo "bundle test: FAIL"
exit "$fail"
