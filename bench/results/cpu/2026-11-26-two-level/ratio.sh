#!/bin/bash
# usage: ratio.sh TLDIR  -> per ray set: flat Mrays/s, tl Mrays/s, ratio (median of 3 each, interleaved)
B=/work/main/build/bin
d=${1:-tl}
for r in kicad_board.board.p kicad_board.board.d kicad_board.parts.p kicad_board.parts.d dense_dragons.ball.p dense_dragons.ball.d dense_dragons.close.p dense_dragons.close.d; do
  n=${r%%.*}
  fs=(); ts=()
  for i in 1 2 3; do
    fs+=($($B/cwbvh trace flat/$n.cwbvh --rays $r.rays --threads 1 2>&1 | awk '/^Mrays/{print $2}'))
    ts+=($($B/cwbvh trace $d/$n.cwbvh --rays $r.rays --threads 1 2>&1 | awk '/^Mrays/{print $2}'))
  done
  tn=$($B/cwbvh trace $d/$n.cwbvh --rays $r.rays --threads 1 2>&1 | awk '/^nodes/{print $2}')
  fn=$($B/cwbvh trace flat/$n.cwbvh --rays $r.rays --threads 1 2>&1 | awk '/^nodes/{print $2}')
  python3 -c "
import statistics,sys
f=statistics.median([float(x) for x in '${fs[*]}'.split()]); t=statistics.median([float(x) for x in '${ts[*]}'.split()])
print(f'{\"$r\":24s} flat {f:7.3f}  two-level {t:7.3f}  ratio {t/f:5.2f}  nodes/ray {$fn} -> {$tn}')"
done
