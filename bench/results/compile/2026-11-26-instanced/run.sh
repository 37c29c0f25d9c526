#!/bin/sh
# Instanced (default) vs --flatten: file bytes and compile seconds, --threads 2,
# runs interleaved (instanced, flattened, instanced, ...) so that the load of the
# shared 2-core machine falls on both alike. Usage (repo root):
#   sh bench/results/compile/2026-11-26-instanced/run.sh build/bin/cwbvhc /work/shared/scenes RUNS
set -e
CWBVHC=${1:-build/bin/cwbvhc}
SCENES=${2:-/work/shared/scenes}
RUNS=${3:-3}
OUT=$(mktemp -d)
echo "scene,mode,run,seconds_wall,seconds_phases,peak_rss_bytes,file_bytes,triangles,instanced_triangles,meshes,instances"
for scene in kicad_board dense_dragons; do
  for run in $(seq 1 "$RUNS"); do
    for mode in instanced flatten; do
      flag=""; [ "$mode" = flatten ] && flag=--flatten
      start=$(date +%s.%N)
      "$CWBVHC" "$SCENES/$scene.glb" -o "$OUT/$scene.$mode.cwbvh" --threads 2 --quiet $flag --stats-json "$OUT/s.json"
      end=$(date +%s.%N)
      python3 - "$OUT/s.json" "$scene" "$mode" "$run" "$start" "$end" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
wall = float(sys.argv[6]) - float(sys.argv[5])
print(f"{sys.argv[2]},{sys.argv[3]},{sys.argv[4]},{wall:.3f},{s['seconds']['total']:.3f},{s['peak_rss_bytes']},"
      f"{s['file_bytes']},{s['triangles']},{s['instanced_triangles']},{s['meshes']},{s['instances']}")
PY
    done
  done
done
rm -rf "$OUT"
