#!/usr/bin/env bash
# Installs dependencies, builds everything (Release) and runs the test suite,
# then rebuilds with AddressSanitizer + UndefinedBehaviorSanitizer and runs the
# tests again. Set CWBVH_SKIP_SANITIZERS=1 to run only the first pass.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
JOBS="$(nproc)"

scripts/setup-debian.sh

echo "== Release build and tests"
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DCWBVH_WERROR=ON >/dev/null
cmake --build build -j"$JOBS"
ctest --test-dir build --output-on-failure --no-tests=error -j"$JOBS"

if [[ "${CWBVH_SKIP_SANITIZERS:-0}" != "1" ]]; then
  echo "== ASan + UBSan build and tests"
  cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCWBVH_SANITIZE=ON \
        -DCWBVH_CUDA=OFF >/dev/null
  cmake --build build-asan -j"$JOBS"
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  LSAN_OPTIONS=suppressions="$ROOT/tests/lsan.supp":print_suppressions=0 \
    ctest --test-dir build-asan --output-on-failure --no-tests=error -j"$JOBS" -LE slow
fi
echo "== all tests passed"
