#!/usr/bin/env bash
# The main job on the default scene: install dependencies, build, compile the
# Stanford bunny (Debian's glmark2-data) into out/bunny.cwbvh, validate it,
# describe it and render it to out/bunny.png (plus a traversal heatmap).
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
build/bin/cwbvh validate --deep "out/$NAME.cwbvh"
build/bin/cwbvh info "out/$NAME.cwbvh"
build/bin/cwbvh render "out/$NAME.cwbvh" -o "out/$NAME.png"
build/bin/cwbvh render "out/$NAME.cwbvh" -o "out/$NAME-heatmap.png" --heatmap
echo "images: out/$NAME.png (shaded; background shows through any hole) and out/$NAME-heatmap.png (wide nodes visited per ray)"
