#!/usr/bin/env python3
"""Writes the DERIVED two-level test scene derived_board_dragons32.glb (issue 19): at
least 100M instanced triangles that cwbvhc keeps as instances (a two-level file), made
from two shipped scenes by glTF instancing:

    kicad_board.glb          x1   the ground: 312 KiCad part meshes placed 1,062 times
                                  (3,939,856 triangles placed, 1,125,502 distinct)
    dragon_loop1_draco.glb   x32  standing dragons, Draco-compressed mesh stored once
                                  (32 x 3,485,656 = 111,540,992 triangles placed)

    115,480,848 triangles placed, 4,611,158 distinct (before cwbvhc drops zero-area ones).

DERIVED: not a real scene. The dragon (y up in its file, 0.205 long) is turned z up,
scaled by 25-45 (5-9 board units long: the size of the larger parts) and placed on a
jittered 8 x 4 grid over the board (216 x 222 units) with a random yaw and its lowest
point on z = 0, so the dragons stand among the parts. Seeded (Python's random.Random,
SEED below): the same file on every machine. Every dragon node names the one dragon
mesh, so the compiled file holds it once.

The GLB merging (buffers, accessors, Draco extension) is make-derived-composite.py's
Builder, imported from beside this script. Python 3 standard library only.

usage: scripts/make-instanced-city.py SCENES_DIR OUT.glb
       (SCENES_DIR holds kicad_board.glb and dragon_loop1_draco.glb; OUT outside the repo,
       e.g. /tmp/derived_board_dragons32.glb)
"""
import importlib.util
import math
import os
import random
import sys

SEED = 2019
NAME = "derived_board_dragons32"
DRAGON = "dragon_loop1_draco.glb"
GROUND = "kicad_board.glb"
COPIES = (8, 4)             # grid columns x rows of dragons
SCALE = (25.0, 45.0)        # the dragon's scale range
BOARD_XY = (0.2, 0.2, 216.76, 221.74)  # kicad_board's bounding box in x and y (SCENES.md)


def composite_module():
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "make-derived-composite.py")
    spec = importlib.util.spec_from_file_location("make_derived_composite", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__.split("usage: ")[1])
    src, out = sys.argv[1], sys.argv[2]
    for name in (GROUND, DRAGON):
        path = os.path.join(src, name)
        if os.path.realpath(out) == os.path.realpath(path) or (
                os.path.exists(out) and os.path.exists(path) and os.path.samefile(out, path)):
            sys.exit(f"{out}: output is the same file as '{path}'; refusing to overwrite it")
    comp = composite_module()
    rng = random.Random(SEED)
    b = comp.Builder()
    b.doc["asset"]["generator"] = "cwbvh scripts/make-instanced-city.py"
    b.place(os.path.join(src, GROUND), label="kicad_board")

    doc, _ = comp.read_glb(os.path.join(src, DRAGON))
    pos = [a for a in doc["accessors"] if a.get("type") == "VEC3" and "min" in a][0]
    lo, hi = pos["min"], pos["max"]
    cx, cz = (lo[0] + hi[0]) / 2, (lo[2] + hi[2]) / 2
    up = (math.sin(math.pi / 4), 0.0, 0.0, math.cos(math.pi / 4))  # +90 deg about x: the file's +y -> +z
    x0, y0, x1, y1 = BOARD_XY
    cols, rows = COPIES
    cell_w, cell_h = (x1 - x0) / cols, (y1 - y0) / rows
    # Each dragon is one node naming the dragon mesh (the file's single root node copied
    # under a placement node): cwbvhc composes them into one world matrix per dragon.
    for k in range(cols * rows):
        i, j = k % cols, k // cols
        s = rng.uniform(*SCALE)
        yaw = rng.uniform(0.0, 2.0 * math.pi)
        px = x0 + (i + rng.uniform(0.25, 0.75)) * cell_w
        py = y0 + (j + rng.uniform(0.25, 0.75)) * cell_h
        # After scale and the turn up, the file's point (x, y, z) is s * (x, -z, y); then the
        # yaw about z; the translation puts the centre over (px, py), the lowest point on z = 0.
        vx, vy, vz = s * cx, -s * cz, s * lo[1]
        c, sn = math.cos(yaw), math.sin(yaw)
        t = (px - (c * vx - sn * vy), py - (sn * vx + c * vy), -vz)
        q = comp.qmul((0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)), up)
        # Rounded, so that a libm whose sin/cos differ in the last bit writes the same file.
        t, q, s = [round(x, 6) for x in t], [round(x, 12) for x in q], round(s, 6)
        b.place(os.path.join(src, DRAGON), translation=t, rotation=q, scale=s, label=f"dragon#{k}")
    note = (f"DERIVED (not a real scene), {NAME}: kicad_board (COMPOSITE of KiCad parts, its instancing kept) "
            f"as the ground and {cols * rows} instances of dragon_loop1_draco (DERIVED, Loop-subdivided Stanford "
            f"dragon) standing among the parts, seeded placement (Python random.Random({SEED})); "
            "scripts/make-instanced-city.py")
    size = b.write(out, note)
    dragons = cols * rows
    print(f"{out}: {size / 1048576:.1f} MiB, {len(b.doc['nodes'])} nodes, {len(b.doc['meshes'])} meshes, "
          f"{dragons} dragons: {3939856 + dragons * 3485656:,} triangles placed")


if __name__ == "__main__":
    main()
