#!/usr/bin/env bash
# Installs dependencies, builds everything (Release) and runs the test suite,
# then rebuilds with AddressSanitizer + UndefinedBehaviorSanitizer and runs the
# tests again, then builds the libFuzzer targets (clang, ASan + UBSan), replays
# the committed corpus through them and fuzzes each for CWBVH_FUZZ_SECONDS
# (default 60; 5 targets). Set CWBVH_SKIP_SANITIZERS=1 to skip the ASan pass,
# CWBVH_SKIP_FUZZ=1 to skip the fuzz step.
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
if [[ "${CWBVH_SKIP_FUZZ:-0}" != "1" ]]; then
  FUZZ_SECONDS="${CWBVH_FUZZ_SECONDS:-60}"
  FUZZ_TARGETS=(validate bvh2 ray_file import trace)
  echo "== libFuzzer (ASan + UBSan): committed corpus once, then ${FUZZ_SECONDS} s per target"
  CC=clang CXX=clang++ cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCWBVH_FUZZ=ON \
        -DCWBVH_SANITIZE=ON -DCWBVH_CUDA=OFF -DCWBVH_BUILD_TESTS=OFF >/dev/null
  cmake --build build-fuzz -j"$JOBS" --target "${FUZZ_TARGETS[@]/#/cwbvh_fuzz_}"
  FUZZ_WORK="$(mktemp -d)"
  mkdir -p build-fuzz/artifacts
  trap 'rm -rf "$FUZZ_WORK"' EXIT
  # Replay: every committed input once (no mutation), under ASan + UBSan.
  for t in validate trace; do
    build-fuzz/bin/cwbvh_fuzz_$t tests/fuzz/corpus/* 2>"$FUZZ_WORK/replay.log" ||
      { tail -50 "$FUZZ_WORK/replay.log"; echo "corpus replay through cwbvh_fuzz_$t failed"; exit 1; }
  done
  for t in "${FUZZ_TARGETS[@]}"; do
    mkdir -p "$FUZZ_WORK/$t"
  done
  cp tests/fuzz/corpus/* "$FUZZ_WORK/validate/"
  cp tests/fuzz/corpus/* "$FUZZ_WORK/trace/"
  # Importer seeds (first byte picks the extension: 2 = .obj, 0 = .gltf).
  printf '\002v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n' >"$FUZZ_WORK/import/seed_obj"
  printf '\000{"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}]}' \
    >"$FUZZ_WORK/import/seed_gltf"
  for t in "${FUZZ_TARGETS[@]}"; do
    # A crashing input is kept in build-fuzz/artifacts/ (the work folder is removed on exit).
    # lsan.supp: OpenMesh's once-per-process log stream (the importer target).
    if ! (cd "$FUZZ_WORK" && LSAN_OPTIONS=suppressions="$ROOT/tests/lsan.supp":print_suppressions=0 \
            "$ROOT/build-fuzz/bin/cwbvh_fuzz_$t" -max_total_time="$FUZZ_SECONDS" -max_len=65536 -timeout=30 \
            -rss_limit_mb=2048 -artifact_prefix="$ROOT/build-fuzz/artifacts/$t-" "$t" 2>"$t.log"); then
      tail -60 "$FUZZ_WORK/$t.log"
      echo "fuzz target cwbvh_fuzz_$t failed"
      exit 1
    fi
    echo "cwbvh_fuzz_$t: $(grep -o 'Done [0-9]* runs in [0-9]* second(s)' "$FUZZ_WORK/$t.log")"
  done
fi
echo "== all tests passed"
