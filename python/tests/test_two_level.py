"""Two-level files (format 1.2) from Python: compile() keeps glTF instancing unless flatten=True,
open() (deep=True: D7 too), info counts, the MESH/INST tables, and Scene.trace over the two-level
traversal against the same scene compiled with flatten=True on the same rays (issue 19's
criterion: hit/miss equal, t within 1e-5 relative, the same source primitive or an equal-t tie),
with each hit's instance checked against the glTF the test writes itself: two meshes, a cube
placed four times (translated, rotated and scaled, mirrored, under a rotated parent) and a
pyramid placed once. Also dense_dragons (shared scene; skipped when absent) on its catalog views,
and the device path's instance column with fake device arrays."""

import json
import math
import struct
import threading

import numpy as np
import pytest

import cwbvh
from conftest import SCENES_DIR, require, run, ticks_while, tool
from test_device_interface import FakeCAI, RecordingHandle

MISS = cwbvh.MISS

# --- the test's own instanced glTF -------------------------------------------------------------

CUBE_V = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)], np.float32)
CUBE_I = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                   [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]], np.uint32)
PYR_V = np.array([[-0.6, 0, -0.6], [0.6, 0, -0.6], [0.6, 0, 0.6], [-0.6, 0, 0.6], [0, 0.9, 0]], np.float32)
PYR_I = np.array([[0, 1, 2], [0, 2, 3], [0, 4, 1], [1, 4, 2], [2, 4, 3], [3, 4, 0]], np.uint32)
MESHES = [(CUBE_V, CUBE_I), (PYR_V, PYR_I)]


def quat(axis, degrees):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    h = math.radians(degrees) / 2
    return [*(axis * math.sin(h)), math.cos(h)]


# glTF nodes: (mesh or None, translation, rotation quaternion xyzw, scale, children)
NODES = [
    (0, [2.0, 0.0, 0.0], None, None, []),
    (0, [-2.0, 1.0, 0.0], quat([1, 2, 3], 40), [1.0, 0.5, 2.0], []),
    (0, [0.0, 0.0, 3.0], None, [-1.0, 1.0, 1.0], []),  # mirrored: negative determinant
    (None, [0.0, -3.0, 0.0], quat([0, 0, 1], 90), None, [4]),
    (0, [1.0, 0.0, 0.0], None, [0.5, 0.5, 0.5], []),  # under node 3
    (1, [0.0, 3.0, -1.0], None, None, []),  # the pyramid, placed once
]
ROOTS = [0, 1, 2, 3, 5]
CUBE_NODES = [0, 1, 2, 4]


def local_matrix(node):
    _, t, r, s, _ = NODES[node]
    m = np.eye(4)
    if s is not None:
        m = np.diag([*s, 1.0]) @ m
    if r is not None:
        x, y, z, w = r
        rot = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        r4 = np.eye(4)
        r4[:3, :3] = rot
        m = r4 @ m
    if t is not None:
        t4 = np.eye(4)
        t4[:3, 3] = t
        m = t4 @ m
    return m


def world_matrices():
    out = {}

    def walk(node, parent):
        m = parent @ local_matrix(node)
        out[node] = m
        for c in NODES[node][4]:
            walk(c, m)

    for r in ROOTS:
        walk(r, np.eye(4))
    return out


def write_glb(path):
    blob, views, accessors = bytearray(), [], []

    def add(array, target, component, kind, minmax=False):
        while len(blob) % 4:
            blob.append(0)
        data = np.ascontiguousarray(array).tobytes()
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data), "target": target})
        blob.extend(data)
        acc = {"bufferView": len(views) - 1, "componentType": component, "count": int(len(array)), "type": kind}
        if minmax:
            acc["min"] = [float(x) for x in array.min(axis=0)]
            acc["max"] = [float(x) for x in array.max(axis=0)]
        accessors.append(acc)
        return len(accessors) - 1

    meshes = []
    for v, i in MESHES:
        pos = add(v, 34962, 5126, "VEC3", minmax=True)
        idx = add(i.reshape(-1), 34963, 5125, "SCALAR")
        meshes.append({"primitives": [{"attributes": {"POSITION": pos}, "indices": idx, "mode": 4}]})
    nodes = []
    for mesh, t, r, s, children in NODES:
        n = {}
        if mesh is not None:
            n["mesh"] = mesh
        if t is not None:
            n["translation"] = t
        if r is not None:
            n["rotation"] = r
        if s is not None:
            n["scale"] = s
        if children:
            n["children"] = children
        nodes.append(n)
    while len(blob) % 4:
        blob.append(0)
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": ROOTS}], "nodes": nodes, "meshes": meshes,
           "accessors": accessors, "bufferViews": views, "buffers": [{"byteLength": len(blob)}]}
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    total = 12 + 8 + len(js) + 8 + len(blob)
    with open(path, "wb") as f:
        f.write(struct.pack("<III", 0x46546C67, 2, total))
        f.write(struct.pack("<II", len(js), 0x4E4F534A) + js)
        f.write(struct.pack("<II", len(blob), 0x004E4942) + bytes(blob))


@pytest.fixture(scope="module")
def instanced_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("instanced")
    glb = d / "instanced.glb"
    write_glb(glb)
    stats = cwbvh.compile(glb, d / "two.cwbvh")
    flat_stats = cwbvh.compile(glb, d / "flat.cwbvh", flatten=True)
    return glb, d / "two.cwbvh", d / "flat.cwbvh", stats, flat_stats


def random_rays(lo, hi, n, seed):
    """Rays from a sphere around the box toward random points inside it (plus their tmin/tmax)."""
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    c, r = (lo + hi) / 2, np.linalg.norm(hi - lo)
    u = rng.normal(size=(n, 3))
    org = c + 1.5 * r * u / np.linalg.norm(u, axis=1, keepdims=True)
    target = lo + rng.random((n, 3)) * (hi - lo)
    d = target - org
    return cwbvh.pack_rays(org, d / np.linalg.norm(d, axis=1, keepdims=True))


def extent(scene):
    lo, hi = scene.info["bounds"]
    return float(max(np.abs(lo).max(), np.abs(hi).max()))


def compare(two, flat, rays, a, b, normals):
    """Issue 19's criterion for closest hits, as tests/traverse/two_level_files_test.cpp checks
    it: hit/miss equal (but for rays within 1e-5 barycentric of a mesh edge: `edge`); t within
    1e-5 relative, or else (a grazing ray) the gap measured along the surface normal,
    |dt| |n.d|, within 16 u of the scene's extent, the rounding of world coordinates both files
    share (`rounding`); the same source primitive or an equal-t tie (`ties`).
    normals(i): unit normals (k, 3) of the triangles hit by rays i. Returns a dict of counts."""
    ha, hb = a.prim != MISS, b.prim != MISS
    assert np.array_equal(ha, a.instance != MISS)
    edge = 0
    for i in np.nonzero(ha != hb)[0]:
        h = a if ha[i] else b
        assert min(h.u[i], h.v[i], 1 - h.u[i] - h.v[i]) <= 1e-5, "ray %d: hit/miss differ off an edge" % i
        edge += 1
    both = np.nonzero(ha & hb)[0]
    gap = np.abs(a.t[both].astype(np.float64) - b.t[both])
    rel = gap / np.abs(b.t[both].astype(np.float64))
    far = rel > 1e-5
    if far.any():
        i = both[far]
        along = gap[far] * np.abs(np.einsum("ij,ij->i", normals(i), rays[i, 4:7].astype(np.float64)))
        slack = 16 * 2.0 ** -24 * extent(flat)
        assert along.max() <= slack, "t differs by %g relative, %g along the normal (> %g)" % (
            rel[far].max(), along.max(), slack)
    sa, sb = two.sources(a.prim[both]), flat.sources(b.prim[both])
    assert not (sa == MISS).any() and not (sb == MISS).any()
    # a different source only as a tie: a triangle met at a t that agrees as closely
    ties = int((~(sa == sb).all(axis=1)).sum())
    return dict(rays=len(rays), hits=len(both), edge=edge, rounding=int(far.sum()), ties=ties,
                worst=float(rel[~far].max()) if (~far).any() else 0.0)


def unit(n):
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def world_triangle(two, instance, prim):
    """The world-space triangle (3, 3) of stored triangle `prim` placed by `instance`, from the
    test's own glTF (the source map names the mesh and triangle, the instance its node)."""
    world = world_matrices()
    mesh, tri = (int(x) for x in two.sources([prim])[0, [1, 3]])
    node = int(two.instances()[instance]["source_node"])
    if node == MISS:  # the merged geometry: placed once, by the node that places that mesh
        node = [n for n, nd in enumerate(NODES) if nd[0] == mesh][0]
    assert NODES[node][0] == mesh, "instance %d (node %d) holds a triangle of mesh %d" % (instance, node, mesh)
    v, idx = MESHES[mesh]
    t = v[idx[tri]].astype(np.float64)
    return (world[node][:3, :3] @ t.T).T + world[node][:3, 3]


def test_compile_keeps_instancing_and_flatten_option(instanced_files):
    glb, two_path, flat_path, stats, flat_stats = instanced_files
    assert stats["two_level"] and not flat_stats["two_level"]
    assert stats["meshes"] == 2 and stats["instances"] == 5  # the cube; the pyramid merged, placed once
    assert stats["triangles"] == 12 + 6 and stats["instanced_triangles"] == 4 * 12 + 6
    assert flat_stats["triangles"] == 4 * 12 + 6
    # the same bytes as cwbvhc (and --flatten)
    run(tool("cwbvhc"), glb, "-o", two_path.parent / "tool.cwbvh", "--quiet")
    run(tool("cwbvhc"), glb, "-o", two_path.parent / "tool_flat.cwbvh", "--flatten", "--quiet")
    assert (two_path.parent / "tool.cwbvh").read_bytes() == two_path.read_bytes()
    assert (two_path.parent / "tool_flat.cwbvh").read_bytes() == flat_path.read_bytes()
    with pytest.raises(TypeError, match="flatten"):
        cwbvh.compile(glb, two_path.parent / "x.cwbvh", flaten=True)


def test_open_info_tables_and_deep(instanced_files):
    _, two_path, flat_path, _, _ = instanced_files
    with cwbvh.open(two_path, deep=True) as two, cwbvh.open(flat_path, deep=True) as flat:
        assert two.is_two_level and not flat.is_two_level
        info = two.info
        assert info["is_two_level"] and info["version"] == (1, 2)
        tl = info["two_level"]
        assert tl["meshes"] == 2 and tl["instances"] == 5 and tl["top_nodes"] >= 1
        assert tl["distinct_triangles"] == 18 == info["triangles"] and tl["instanced_triangles"] == 54
        assert {"MESH", "INST", "TLAS"} <= {s for s, _ in info["sections"]}
        assert flat.info["two_level"] is None and not flat.info["is_two_level"]
        assert len(flat.meshes()) == 0 and len(flat.instances()) == 0
        # `cwbvh info --json` reports the same counts
        js = json.loads(run(tool("cwbvh"), "info", two_path, "--json"))
        assert js["two_level"] == {k: tl[k] for k in js["two_level"]}
        meshes, inst = two.meshes(), two.instances()
        assert meshes.dtype == cwbvh.MESH_DTYPE and inst.dtype == cwbvh.INSTANCE_DTYPE
        assert not inst.flags.writeable and len(inst) == 5 and len(meshes) == 2
        assert list(meshes["prim_count"]) == [12, 6] and list(meshes["source_mesh"]) == [0, MISS]
        # each cube placement carries its node's world transform; the merged pyramid the identity
        world = world_matrices()
        nodes = sorted(int(n) for n in inst["source_node"])
        assert nodes == CUBE_NODES + [MISS]
        for rec in inst:
            if rec["source_node"] == MISS:
                assert rec["mesh"] == 1 and np.array_equal(rec["object_to_world"], np.eye(4)[:3])
                continue
            assert rec["mesh"] == 0
            m = world[int(rec["source_node"])][:3]
            assert np.allclose(rec["object_to_world"], m, atol=1e-6)
            assert np.allclose(rec["world_to_object"], np.linalg.inv(world[int(rec["source_node"])])[:3], atol=1e-5)
        mirrored = [r for r in inst if r["source_node"] == 2][0]
        assert np.linalg.det(mirrored["object_to_world"][:, :3]) < 0


def test_deep_runs_d7(instanced_files, tmp_path):
    """An instance's world box shrunk below its transformed mesh box passes the loader
    (checksums off) but not deep=True (D7), with `cwbvh validate --deep`'s message."""
    _, two_path, _, _, _ = instanced_files
    with cwbvh.open(two_path) as two:
        inst = two.instances()
        sections = two.info["sections"]
    data = bytearray(two_path.read_bytes())
    # INST world_hi.x of instance 0: find the record through the section table of `cwbvh info`
    js = json.loads(run(tool("cwbvh"), "info", two_path, "--json"))
    entry = [s for s in js["sections"] if s["type"] == "INST"][0]
    off = entry["offset"] + 116  # InstanceRecord::world_hi
    hi = inst[0]["world_hi"][0]
    lo = inst[0]["world_lo"][0]
    struct.pack_into("<f", data, off, float(lo + 0.25 * (hi - lo)))  # the world box no longer holds the mesh
    bad = tmp_path / "shrunk.cwbvh"
    bad.write_bytes(data)
    assert "INST" in [s for s, _ in sections]
    cwbvh.open(bad, verify_checksums=False).close()  # structurally valid
    with pytest.raises(cwbvh.Error) as e:
        cwbvh.open(bad, verify_checksums=False, deep=True)
    assert "deep check D7: instance 0" in str(e.value)
    p = run_validate(bad)
    assert p.returncode == 1 and p.stderr.strip().endswith(str(e.value))


def run_validate(path):
    import subprocess
    return subprocess.run([tool("cwbvh"), "validate", "--deep", "--no-checksums", str(path)], capture_output=True,
                          text=True)


def check_hit_points(two, rays, h):
    """Every two-level hit lies on its source triangle placed by its instance's glTF node."""
    hit = np.nonzero(h.prim != MISS)[0]
    assert hit.size > 0
    for i in hit:
        tri = world_triangle(two, h.instance[i], h.prim[i])
        p_bary = (1 - h.u[i] - h.v[i]) * tri[0] + h.u[i] * tri[1] + h.v[i] * tri[2]
        p_ray = rays[i, 0:3].astype(np.float64) + h.t[i] * rays[i, 4:7]
        assert np.abs(p_bary - p_ray).max() < 1e-4, "ray %d: hit point off its triangle" % i


def test_trace_matches_flattened(instanced_files):
    _, two_path, flat_path, _, _ = instanced_files
    with cwbvh.open(two_path) as two, cwbvh.open(flat_path, deep=True) as flat:
        lo, hi = two.info["bounds"]
        rays = np.concatenate([random_rays(lo, hi, 20000, 1), cwbvh.camera_rays(two, width=96, height=96)])
        a, b = two.trace(rays), flat.trace(rays)
        assert b.instance is None  # single-level: no instance column, as before
        assert a.instance.dtype == np.uint32 and a.instance.shape == (len(rays),)
        assert a.stats["stack_overflows"] == 0 and a.stats["bad_indices"] == 0
        def normals(idx):
            tris = np.array([world_triangle(two, a.instance[i], a.prim[i]) for i in idx])
            return unit(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]))

        c = compare(two, flat, rays, a, b, normals)
        assert c["hits"] > len(rays) // 10 and c["edge"] * 10000 <= len(rays) and c["ties"] * 1000 <= c["hits"]
        assert c["rounding"] * 1000 <= c["hits"]
        # instances valid: in range, each hit's prim inside its instance's mesh
        hit = a.prim != MISS
        assert np.all(a.instance[hit] < 5) and np.all(a.instance[~hit] == MISS)
        m = two.meshes()[two.instances()["mesh"][a.instance[hit]]]
        assert np.all((a.prim[hit] >= m["prim_first"]) & (a.prim[hit] < m["prim_first"] + m["prim_count"]))
        assert len(np.unique(a.instance[hit])) == 5  # every placement seen, the mirrored one too
        check_hit_points(two, rays, a)
        # the mirrored cube: the same hits as the flattened file (watertight, same source triangle)
        mirrored = int(np.nonzero(two.instances()["source_node"] == 2)[0][0])
        on_mirror = a.instance == mirrored
        assert on_mirror.sum() > 100
        assert np.array_equal(two.sources(a.prim[on_mirror]), flat.sources(b.prim[on_mirror]))
        # any hit: hit exactly when the closest query hits
        any_a, any_b = two.trace(rays, any_hit=True), flat.trace(rays, any_hit=True)
        assert np.sum((any_a.prim != MISS) != (any_b.prim != MISS)) <= c["edge"]
        assert np.array_equal(any_a.prim != MISS, any_a.instance != MISS)
        print("instanced.glb: %s" % c)


def test_trace_input_forms_threads_and_gil(instanced_files):
    _, two_path, _, _, _ = instanced_files
    with cwbvh.open(two_path) as two:
        lo, hi = two.info["bounds"]
        rays = random_rays(lo, hi, 5000, 2)
        ref = two.trace(rays)
        ref_bits = ref.records.view(np.uint32)
        t, u, v, prim = ref  # unpacks as before
        assert np.shares_memory(t, ref.records)
        split = two.trace(np.ascontiguousarray(rays[:, 0:3]), np.ascontiguousarray(rays[:, 4:7]))
        strided = two.trace(np.repeat(rays, 2, axis=0)[::2])
        assert not strided.stats["zero_copy"] and ref.stats["zero_copy"]
        for h in (split, strided, *(two.trace(rays, threads=n) for n in (1, 2, 3))):
            assert np.array_equal(h.records.view(np.uint32), ref_bits) and np.array_equal(h.instance, ref.instance)
        # tmin/tmax with (N, 3) rays: nothing hit beyond tmax
        short = two.trace(rays[:, 0:3].copy(), rays[:, 4:7].copy(), tmax=float(np.median(ref.t[ref.prim != MISS])))
        assert 0 < (short.prim != MISS).sum() < (ref.prim != MISS).sum()
        assert np.all(short.instance[short.prim == MISS] == MISS)
        # several Python threads at once
        results, errors = [None] * 4, []

        def work(i):
            try:
                h = two.trace(rays, threads=1 + i % 2)
                results[i] = (h.records.view(np.uint32), h.instance)
            except Exception as e:  # noqa: BLE001 - reported below
                errors.append(e)

        threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
        for th in threads:
            th.start()
        for th in threads:
            th.join()
        assert not errors
        assert all(np.array_equal(r, ref_bits) and np.array_equal(i, ref.instance) for r, i in results)
        # the GIL is released while the two-level trace runs
        many = random_rays(lo, hi, 400000, 3)
        seconds, during = ticks_while(lambda: two.trace(many, threads=1))
        assert seconds > 0.02
        assert len(during) >= 3, "the ticker did not run: GIL held?"


def test_diffuse_rays_bounce_off_world_triangles(instanced_files):
    """diffuse_rays on a two-level file bounces off the instance's world triangle: the rays match
    the flattened file's (same paths, origins within rounding)."""
    _, two_path, flat_path, _, _ = instanced_files
    with cwbvh.open(two_path) as two, cwbvh.open(flat_path) as flat:
        primary = cwbvh.camera_rays(two, width=64, height=64)
        ra, pa = cwbvh.diffuse_rays(two, primary)
        rb, pb = cwbvh.diffuse_rays(flat, primary)
        assert len(ra) > 100 and np.array_equal(pa, pb)
        assert np.abs(ra[:, 0:3] - rb[:, 0:3]).max() < 1e-4
        both = (two.trace(ra).prim != MISS) == (flat.trace(ra).prim != MISS)
        assert both.mean() > 0.99


def test_rays_bit_identical_to_cwbvh_rays(instanced_files, tmp_path):
    """camera_rays and diffuse_rays on a two-level file are `cwbvh rays`'s to the bit (the scene
    is not in the view catalog: its one view is "default", by name too)."""
    _, two_path, _, _, _ = instanced_files
    with cwbvh.open(two_path) as two:
        assert [v["name"] for v in cwbvh.views(two)] == ["default"]
        primary = cwbvh.camera_rays(two, width=64, height=64)
        assert np.array_equal(cwbvh.camera_rays(two, view="default", width=64, height=64), primary)
        with pytest.raises(ValueError, match="no views"):
            cwbvh.camera_rays(two, view="front", width=4, height=4)
        diffuse, _ = cwbvh.diffuse_rays(two, primary)
        for kind, ours in (("primary", primary), ("diffuse", diffuse)):
            out = tmp_path / kind
            run(tool("cwbvh"), "rays", two_path, "--" + kind, "--width", 64, "--height", 64, "-o", out)
            assert np.array_equal(cwbvh.read_rays(out).view(np.uint32), ours.view(np.uint32))


def test_read_hits_with_instances(instanced_files, tmp_path):
    _, two_path, _, _, _ = instanced_files
    with cwbvh.open(two_path) as two:
        rays_path, hits_path = tmp_path / "p.rays", tmp_path / "p.hits"
        run(tool("cwbvh"), "rays", two_path, "--primary", "--width", "32", "--height", "32", "-o", rays_path)
        run(tool("cwbvh"), "trace", two_path, "--rays", rays_path, "--hits", hits_path)
        records, inst, _ = cwbvh.read_hits(hits_path, instances=True)
        h = two.trace(cwbvh.read_rays(rays_path))
        assert np.array_equal(records.view(np.uint32), h.records.view(np.uint32))
        assert np.array_equal(inst, h.instance)
        with pytest.raises(cwbvh.Error):
            cwbvh.read_hits(hits_path)  # the 16-byte reader refuses instance hits by name


class TwoLevelRecordingHandle(RecordingHandle):
    """RecordingHandle whose "device" buffer holds n Hit records then n instance ids, as
    device_trace.cpp lays out a two-level trace."""

    def trace_device(self, org, org_row, dir_, dir_row, n, tmin, tmax, stream, any_hit, watertight):
        self.calls.append(dict(org=org, n=n, stream=stream))
        buf = np.zeros(5 * n, np.uint32)
        buf[4 * n:] = np.arange(n, dtype=np.uint32)
        return self.wrap(buf)


def test_device_path_instance_column(instanced_files, bunny_file):
    _, two_path, _, _, _ = instanced_files
    scene = cwbvh.open(two_path)
    scene._h = TwoLevelRecordingHandle(scene._h)
    try:
        rays = cwbvh.camera_rays(scene, width=8, height=8)
        hits = scene.trace(FakeCAI(rays, stream=7))
        buf = scene._h.buffers[-1]
        cai = hits.instance.__cuda_array_interface__
        assert cai["data"][0] == buf.ctypes.data + 16 * len(rays) and cai["shape"] == (len(rays),)
        assert cai["strides"] == (4,) and cai["typestr"] == "<u4" and cai["stream"] == 7
        assert hits.prim.__cuda_array_interface__["data"][0] == buf.ctypes.data + 12
    finally:
        scene._h.real.close()
    # a single-level file on the device: no instance column
    flat = cwbvh.open(bunny_file)
    flat._h = RecordingHandle(flat._h)
    try:
        assert flat.trace(FakeCAI(cwbvh.camera_rays(flat, width=4, height=4))).instance is None
    finally:
        flat._h.real.close()


@pytest.mark.skipif(cwbvh.gpu_status()[0] != "ready", reason="needs a GPU (the device path waits for one)")
def test_gpu_two_level_matches_cpu(instanced_files):
    cupy = pytest.importorskip("cupy")
    _, two_path, _, _, _ = instanced_files
    with cwbvh.open(two_path) as two:
        lo, hi = two.info["bounds"]
        rays = random_rays(lo, hi, 20000, 4)
        expected = two.trace(rays)
        two.to_device()
        got = two.trace(cupy.asarray(rays))
        assert np.array_equal(cupy.asnumpy(got.records).view(np.uint32), expected.records.view(np.uint32))
        assert np.array_equal(cupy.asnumpy(got.instance), expected.instance)


# --- dense_dragons: one mesh placed 200 times --------------------------------------------------

@pytest.fixture(scope="module")
def dragons(tmp_path_factory):
    src = require(SCENES_DIR / "dense_dragons.glb", "shared scene")
    d = tmp_path_factory.mktemp("dragons")
    cwbvh.compile(src, d / "dense_dragons.cwbvh")
    # keep_mesh (it implies flatten) for the normals of the criterion; the same tree and hits
    cwbvh.compile(src, d / "dense_dragons_flat.cwbvh", flatten=True, keep_mesh=True)
    return d / "dense_dragons.cwbvh", d / "dense_dragons_flat.cwbvh"


def test_dense_dragons_matches_flattened(dragons):
    two_path, flat_path = dragons
    with cwbvh.open(two_path, deep=True) as two, cwbvh.open(flat_path) as flat:
        tl = two.info["two_level"]
        assert tl["meshes"] == 1 and tl["instances"] == 200
        assert tl["instanced_triangles"] == 200 * tl["distinct_triangles"] == flat.info["triangles"]
        flat_bytes = flat_path.stat().st_size - sum(n for s, n in flat.info["sections"] if s in ("VERT", "INDX"))
        assert two_path.stat().st_size * 20 <= flat_bytes  # issue 19: at most 1/20 of the flattened file
        verts, idx = flat.vertices(), flat.indices()
        views = cwbvh.views(two)
        assert [v["name"] for v in views] == ["ball", "close"]
        for v in views:
            rays = cwbvh.camera_rays(two, view=v["name"], width=128, height=128)
            a, b = two.trace(rays), flat.trace(rays)

            def normals(i):  # of the flattened file's stored triangles hit by rays i
                tri = verts[idx[b.prim[i]]].astype(np.float64)
                return unit(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))

            c = compare(two, flat, rays, a, b, normals)
            assert c["hits"] > len(rays) // 10 and c["edge"] * 10000 <= len(rays)
            # dense_dragons' dragon has coincident triangles: ~1% of its primary hits are exact ties
            assert c["ties"] * 20 <= c["hits"]
            # grazing rays whose t agrees only to the rounding along the normal: rare
            assert c["rounding"] * 10000 <= c["rays"]
            hit = a.prim != MISS
            assert np.all(a.instance[hit] < 200) and len(np.unique(a.instance[hit])) > 10
            print("dense_dragons %s: %s" % (v["name"], c))
