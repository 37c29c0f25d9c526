#!/usr/bin/env bash
# Packs cwbvhc with every shared library it loads into one folder that runs on a
# machine without the Debian packages (the lent GPU machine: Ubuntu 24.04, no Embree,
# OpenMesh, Draco or oneTBB), and xz-compresses it for the device tool's 64 MiB carry:
#
#   gpu_inputs/cwbvhc-bundle.tar.xz  ->  cwbvhc-bundle/
#       cwbvhc          the wrapper to run (a shell script)
#       bin/cwbvhc      the binary as built here
#       lib/            every library ldd lists, glibc and its loader included
#
# How it starts, and why: the wrapper runs the bundled dynamic loader explicitly,
#   lib/ld-linux-x86-64.so.2 --library-path lib --inhibit-cache --argv0 cwbvhc bin/cwbvhc ...
# with LD_LIBRARY_PATH, LD_PRELOAD and LD_AUDIT unset. --library-path puts the bundle
# first for every library and every dlopen; --inhibit-cache skips /etc/ld.so.cache, so
# a library the bundle lacked would fail to load or show up in LD_DEBUG=libs instead of
# being silently taken from the host's cache. Bundling glibc too (rather than RPATH
# $ORIGIN on the host's loader) means the same libc and libm as here: cwbvhc promises
# byte-identical output, and libm's results for the few transcendental calls may differ
# between glibc versions; the host's glibc (2.39 there, 2.36 here) is never used. The
# kernel ABI is all it needs from the host.
#
# usage: scripts/bundle-cwbvhc.sh [CWBVHC]   (default: build/bin/cwbvhc, built if missing)
# env:   OUT=path of the .tar.xz (default gpu_inputs/cwbvhc-bundle.tar.xz)
# Check it: scripts/test-cwbvhc-bundle.sh (clean environment, LD_DEBUG, byte-identical output).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cwbvhc=${1:-$root/build/bin/cwbvhc}
out=${OUT:-$root/gpu_inputs/cwbvhc-bundle.tar.xz}
if [[ ! -x "$cwbvhc" ]]; then
  cmake -S "$root" -B "$root/build" -G Ninja >/dev/null
  ninja -C "$root/build" -j2 cwbvhc
fi
stage=$(mktemp -d)
trap 'rm -rf "$stage"' EXIT
b="$stage/cwbvhc-bundle"
mkdir -p "$b/bin" "$b/lib"
cp "$cwbvhc" "$b/bin/cwbvhc"
# Every library the loader resolves (ldd follows the dependencies of dependencies),
# plus the loader itself (the "/lib64/ld-linux-x86-64.so.2 (0x...)" line).
mapfile -t libs < <(ldd "$cwbvhc" | awk '$2 == "=>" && $3 ~ /^\// {print $3} $1 ~ /^\// {print $1}')
loader=""
for l in "${libs[@]}"; do
  real=$(readlink -f "$l")
  cp "$real" "$b/lib/$(basename "$l")"  # under the soname the binary asks for
  [[ "$(basename "$l")" == ld-linux-* ]] && loader=$(basename "$l")
done
[[ -n "$loader" ]] || { echo "bundle-cwbvhc: no dynamic loader in ldd's output" >&2; exit 1; }
# Libraries some of these open at run time (dlopen) rather than link: oneTBB's
# allocator proxy. Added when present so --inhibit-cache never reaches for the host's.
for extra in libtbbmalloc.so.2; do
  p=$(ldconfig -p | awk -v n="$extra" '$1 == n && /x86-64/ && !found {print $NF; found = 1}')  # no early exit: under pipefail a SIGPIPE'd ldconfig failed the script (exit 141)
  [[ -n "$p" ]] && cp "$(readlink -f "$p")" "$b/lib/$extra"
done
cat > "$b/cwbvhc" <<EOF
#!/bin/sh
# cwbvhc from the bundle: its own loader, glibc and libraries only (scripts/bundle-cwbvhc.sh).
d=\$(cd "\$(dirname "\$0")" && pwd)
unset LD_LIBRARY_PATH LD_PRELOAD LD_AUDIT
exec "\$d/lib/$loader" --library-path "\$d/lib" --inhibit-cache --argv0 cwbvhc "\$d/bin/cwbvhc" "\$@"
EOF
chmod +x "$b/cwbvhc" "$b/lib/$loader"
{
  echo "cwbvhc bundle: $(cd "$root" && git rev-parse --short HEAD 2>/dev/null || echo unknown) $(date -u +%F)"
  echo "built on: $(. /etc/os-release && echo "$PRETTY_NAME"), $(ldd --version | head -1)"
  (cd "$b/lib" && ls -1)
} > "$b/MANIFEST"
mkdir -p "$(dirname "$out")"
tar -C "$stage" -cf - cwbvhc-bundle | xz -T2 -9 > "$out.tmp"
mv "$out.tmp" "$out"
echo "$(basename "$out"): $(( $(stat -c %s "$out") >> 10 )) KiB ($(du -sb "$b" | cut -f1 | awk '{printf "%.1f", $1/1048576}') MiB unpacked, ${#libs[@]} libraries)"
