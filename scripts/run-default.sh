#!/usr/bin/env bash
# The main job on the default scene: install dependencies, build, compile the
# Stanford bunny (Debian's glmark2-data) into out/bunny.cwbvh, validate it,
# describe it and render it to out/bunny.png.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

scripts/setup-debian.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)"

SCENE="${1:-/usr/share/glmark2/models/bunny.obj}"
NAME="$(basename "${SCENE%.*}")"
mkdir -p out
build/bin/cwbvhc "$SCENE" -o "out/$NAME.cwbvh" --stats-json "out/$NAME.stats.json"
build/bin/cwbvh validate "out/$NAME.cwbvh"
build/bin/cwbvh info "out/$NAME.cwbvh"
if build/bin/cwbvh help 2>/dev/null | grep -q render; then
  build/bin/cwbvh render "out/$NAME.cwbvh" -o "out/$NAME.png"
  echo "image: out/$NAME.png"
fi
