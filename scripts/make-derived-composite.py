#!/usr/bin/env python3
"""Writes the DERIVED composite scene derived_board_dragons.glb (issue 18): 12.65M
triangles in the paper's 80k-12.8M range, made only from scenes that travel to the GPU
machine anyway, by glTF instancing (cwbvhc flattens the node transforms).

    kicad_board.glb          x1  the ground: ~1,000 KiCad parts on the z = 0 plane (3,939,856)
    dragon_loop1_draco.glb   x2  standing dragons, Draco-compressed mesh copied as is (2 x 3,485,656)
    dragon.glb               x2  standing dragons (2 x 871,414)

DERIVED: not a real scene. The four dragons (y up in their files) are turned z up,
scaled by 330-450 (68-92 board units long, 48-65 tall: about a third of the board's
216 x 222 extent; their lowest point on z = 0) and placed by a seeded RNG (Python's random.Random,
SEED below) with a random yaw, so they overlap the parts and each other: large smooth
surfaces over a dense field of small CAD parts. Meshes are stored once and referenced
by several nodes; the output holds the three sources' binary chunks unchanged.

Python 3 standard library only, so it runs on the GPU machine (scripts/gpu-check.sh),
which receives the three GLBs but no compiled file of this size.

usage: scripts/make-derived-composite.py SCENES_DIR OUT.glb
       (SCENES_DIR holds dragon.glb, dragon_loop1_draco.glb, kicad_board.glb; xz-compressed
       NAME.glb.xz copies are read too)
"""
import json
import lzma
import math
import os
import random
import struct
import sys

SEED = 2017
NAME = "derived_board_dragons"
# (source file, copies, scale range): the dragon is 0.205 wide, 0.144 tall in its file.
PLACED = [("dragon_loop1_draco.glb", 2, (380.0, 450.0)), ("dragon.glb", 2, (330.0, 400.0))]
GROUND = "kicad_board.glb"
BOARD_XY = (0.2, 0.2, 216.76, 221.74)  # kicad_board's bounding box in x and y (SCENES.md)


def read_glb(path):
    """(json dict, bin bytes) of a GLB, from PATH or PATH.xz."""
    if os.path.exists(path):
        data = open(path, "rb").read()
    elif os.path.exists(path + ".xz"):
        data = lzma.open(path + ".xz").read()
    else:
        sys.exit(f"make-derived-composite: {path}: not found (nor {path}.xz)")
    magic, version, length = struct.unpack_from("<III", data, 0)
    if magic != 0x46546C67 or version != 2 or length != len(data):
        sys.exit(f"make-derived-composite: {path}: not a glTF 2.0 binary")
    off, doc, blob = 12, None, b""
    while off < length:
        clen, ctype = struct.unpack_from("<II", data, off)
        chunk = data[off + 8:off + 8 + clen]
        if ctype == 0x4E4F534A:
            doc = json.loads(chunk)
        elif ctype == 0x004E4942:
            blob = chunk
        off += 8 + clen
    if doc is None or len(doc.get("buffers", [])) > 1 or any("uri" in b for b in doc.get("buffers", [])):
        sys.exit(f"make-derived-composite: {path}: expected one embedded buffer")
    return doc, blob


def qmul(a, b):
    """Hamilton product of quaternions (x, y, z, w)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


class Builder:
    def __init__(self):
        self.doc = {"asset": {"version": "2.0", "generator": "cwbvh scripts/make-derived-composite.py"},
                    "scene": 0, "scenes": [{"nodes": []}], "nodes": [], "meshes": [], "accessors": [],
                    "bufferViews": [], "buffers": [{"byteLength": 0}]}
        self.blob = bytearray()
        self.sources = {}  # file -> (its doc, mesh index offset), meshes added once
        self.extensions = set()

    def add_source(self, path):
        name = os.path.basename(path)
        if name in self.sources:
            return self.sources[name]
        doc, blob = read_glb(path)
        while len(self.blob) % 16:
            self.blob.append(0)
        base, bv0, acc0, mesh0 = len(self.blob), len(self.doc["bufferViews"]), len(self.doc["accessors"]), len(
            self.doc["meshes"])
        self.blob += blob
        for bv in doc.get("bufferViews", []):
            bv = dict(bv, buffer=0, byteOffset=bv.get("byteOffset", 0) + base)
            self.doc["bufferViews"].append(bv)
        for acc in doc.get("accessors", []):
            acc = dict(acc)
            if "bufferView" in acc:
                acc["bufferView"] += bv0
            if "sparse" in acc:
                sys.exit(f"make-derived-composite: {path}: sparse accessors are not handled")
            self.doc["accessors"].append(acc)
        for mesh in doc.get("meshes", []):
            prims = []
            for p in mesh["primitives"]:
                p = json.loads(json.dumps(p))
                p["attributes"] = {k: v + acc0 for k, v in p["attributes"].items()}
                if "indices" in p:
                    p["indices"] += acc0
                p.pop("material", None)
                draco = p.get("extensions", {}).get("KHR_draco_mesh_compression")
                if draco:
                    draco["bufferView"] += bv0  # its attribute ids are Draco's own: unchanged
                    self.extensions.add("KHR_draco_mesh_compression")
                prims.append(p)
            self.doc["meshes"].append({"name": mesh.get("name", name), "primitives": prims})
        self.sources[name] = (doc, mesh0)
        return self.sources[name]

    def place(self, path, translation=None, rotation=None, scale=None, label=""):
        """A copy of PATH's default scene under one new root node with this transform."""
        doc, mesh0 = self.add_source(path)
        nodes = self.doc["nodes"]

        def copy(i):
            src = doc["nodes"][i]
            n = {k: v for k, v in src.items() if k in ("translation", "rotation", "scale", "matrix", "name")}
            if "mesh" in src:
                n["mesh"] = src["mesh"] + mesh0
            kids = [copy(c) for c in src.get("children", [])]
            if kids:
                n["children"] = kids
            nodes.append(n)
            return len(nodes) - 1

        scene = doc["scenes"][doc.get("scene", 0)]
        root = {"name": label or os.path.basename(path), "children": [copy(i) for i in scene["nodes"]]}
        if translation:
            root["translation"] = list(translation)
        if rotation:
            root["rotation"] = list(rotation)
        if scale:
            root["scale"] = [scale] * 3
        nodes.append(root)
        self.doc["scenes"][0]["nodes"].append(len(nodes) - 1)

    def write(self, out, source_note):
        while len(self.blob) % 4:
            self.blob.append(0)
        self.doc["buffers"][0]["byteLength"] = len(self.blob)
        self.doc["asset"]["extras"] = {"source": source_note}
        if self.extensions:
            self.doc["extensionsUsed"] = sorted(self.extensions)
            self.doc["extensionsRequired"] = sorted(self.extensions)
        js = json.dumps(self.doc, separators=(",", ":")).encode()
        js += b" " * (-len(js) % 4)
        total = 12 + 8 + len(js) + 8 + len(self.blob)
        tmp = out + ".tmp"
        with open(tmp, "wb") as f:
            f.write(struct.pack("<III", 0x46546C67, 2, total))
            f.write(struct.pack("<II", len(js), 0x4E4F534A) + js)
            f.write(struct.pack("<II", len(self.blob), 0x004E4942))
            f.write(self.blob)
        os.replace(tmp, out)
        return total


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__.split("usage: ")[1])
    src, out = sys.argv[1], sys.argv[2]
    # Never overwrite an input: the output must not be (a link to) one of the source GLBs.
    for name in [GROUND] + [n for n, _, _ in PLACED]:
        path = os.path.join(src, name)
        if os.path.realpath(out) == os.path.realpath(path) or (
                os.path.exists(out) and os.path.exists(path) and os.path.samefile(out, path)):
            sys.exit(f"{out}: output is the same file as '{path}'; refusing to overwrite it")
    rng = random.Random(SEED)
    b = Builder()
    b.place(os.path.join(src, GROUND), label="kicad_board")
    x0, y0, x1, y1 = BOARD_XY
    up = (math.sin(math.pi / 4), 0.0, 0.0, math.cos(math.pi / 4))  # +90 deg about x: the file's +y -> +z
    placements = []
    for name, copies, (smin, smax) in PLACED:
        doc, _ = read_glb(os.path.join(src, name))  # the bounds of its one positions accessor
        pos = [a for a in doc["accessors"] if a.get("type") == "VEC3" and "min" in a][0]
        lo, hi = pos["min"], pos["max"]
        cx, cz = (lo[0] + hi[0]) / 2, (lo[2] + hi[2]) / 2
        for k in range(copies):
            s = rng.uniform(smin, smax)
            yaw = rng.uniform(0.0, 2.0 * math.pi)
            px, py = rng.uniform(x0 + 30, x1 - 30), rng.uniform(y0 + 30, y1 - 30)
            # After scale and the turn up, the file's point (x, y, z) is s * (x, -z, y);
            # then the yaw about z; the translation puts the centre over (px, py) and the
            # lowest point (file y = lo[1]) on z = 0.
            vx, vy, vz = s * cx, -s * cz, s * lo[1]
            c, sn = math.cos(yaw), math.sin(yaw)
            t = (px - (c * vx - sn * vy), py - (sn * vx + c * vy), -vz)
            q = qmul((0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)), up)
            # Rounded, so that a libm whose sin/cos differ in the last bit (glibc 2.36 here,
            # 2.39 on the GPU machine) still writes the same file.
            t, q, s = [round(x, 6) for x in t], [round(x, 12) for x in q], round(s, 6)
            b.place(os.path.join(src, name), translation=t, rotation=q, scale=s, label=f"{name}#{k}")
            placements.append(f"{name} scale {s:.1f} yaw {math.degrees(yaw):.1f} at ({px:.1f}, {py:.1f})")
    note = ("DERIVED composite (not a real scene): kicad_board (COMPOSITE of KiCad parts) as the ground, "
            "2 copies of dragon_loop1_draco (DERIVED, Loop-subdivided Stanford dragon) and 2 of the Stanford "
            f"dragon standing on it, seeded placement (Python random.Random({SEED})); "
            "scripts/make-derived-composite.py")
    size = b.write(out, note)
    print(f"{out}: {size / 1048576:.1f} MiB, {len(b.doc['nodes'])} nodes, {len(b.doc['meshes'])} meshes")
    for p in placements:
        print("  " + p)


if __name__ == "__main__":
    main()
