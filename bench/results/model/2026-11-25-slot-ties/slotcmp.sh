#!/bin/bash
# usage: slotcmp.sh OLD_DIR NEW_DIR scene:view...
B=/work/main/build/bin/cwbvh
old=$1; new=$2; shift 2
printf "%-28s %-8s %10s %10s %10s %10s %8s %8s\n" view rays nodes_old nodes_new tris_old tris_new instr_o instr_n
for sv in "$@"; do sc=${sv%%:*}; v=${sv#*:}
  for kind in primary diffuse; do
    $B rays $old/$sc.cwbvh --$kind --view $v -o /dev/shm/tb/r.bin >/dev/null 2>&1 || { echo "rays failed $sv"; continue; }
    o=$($B model $old/$sc.cwbvh --rays /dev/shm/tb/r.bin 2>&1); n=$($B model $new/$sc/$sc.cwbvh --rays /dev/shm/tb/r.bin 2>&1)
    g(){ echo "$1" | awk -v k="$2" '$0 ~ "^"k {print $2; exit}'; }
    printf "%-28s %-8s %10s %10s %10s %10s %8s %8s\n" "$sc:$v" $kind $(g "$o" "nodes/ray") $(g "$n" "nodes/ray") $(g "$o" "triangles/ray") $(g "$n" "triangles/ray") $(g "$o" "instr/ray") $(g "$n" "instr/ray")
  done
done
