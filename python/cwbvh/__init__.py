"""cwbvh from Python: compile meshes into .cwbvh files, open them in milliseconds (mmap +
validation, no BVH build) and trace rays on the CPU (multi-threaded, GIL released) or the GPU.

    import cwbvh, numpy as np
    stats = cwbvh.compile(["bunny.obj"], "bunny.cwbvh")          # cwbvhc's options as keywords
    scene = cwbvh.open("bunny.cwbvh")
    rays = cwbvh.camera_rays(scene, width=640, height=480)      # (N, 8) float32
    t, u, v, prim = scene.trace(rays)                           # prim == cwbvh.MISS: no hit
    hits = scene.trace(rays); hits.instance                     # two-level files: INST id per hit

Copies: (N, 8) float32 rays in the ray-file layout (origin, tmin, direction, tmax), C-contiguous,
are traced in place; origins + directions (N, 3), or strided rays, are packed once into that
layout (in C++, in parallel, without the GIL). The hits come back as views of one (N, 4) buffer
(no copy): t float32 (inf for a miss), u, v float32 barycentrics of v1 and v2, prim uint32 (the
stored triangle id; MISS for a miss).

Two-level files (format 1.2: a glTF whose meshes are placed by several nodes compiles to one by
default; flatten=True gives the single-level file): one bottom-level tree per distinct mesh, an
instance table and a top-level tree. open() and trace() take them as they are; each hit then also
names its instance (Hits.instance, uint32, MISS for a miss), t is in the parameter of the given
ray, prim is the stored id of the triangle in its mesh (Scene.sources maps it to the glTF source).
"""

import json as _json
import math as _math

import numpy as _np

from . import _args, _arrays, _cwbvh
from ._paths import fspath as _fspath
from ._cwbvh import Error, built_with_cuda, gpu_status
from .rays import camera_rays, diffuse_rays, pack_rays, read_hits, read_rays, view, views

__all__ = ["compile", "open", "Scene", "Hits", "Error", "MISS", "MESH_DTYPE", "INSTANCE_DTYPE", "camera_rays", "diffuse_rays", "pack_rays",
           "read_rays", "read_hits", "view", "views", "gpu_status", "built_with_cuda"]

MISS = 0xFFFFFFFF  #: prim (and instance) of a ray that hit nothing

#: A MESH record of a two-level file (spec 3.9): one bottom level (Scene.meshes()).
MESH_DTYPE = _np.dtype([("node_first", "<u4"), ("node_count", "<u4"), ("tri_first", "<u4"), ("tri_count", "<u4"),
                        ("prim_first", "<u4"), ("prim_count", "<u4"), ("lo", "<f4", (3,)), ("hi", "<f4", (3,)),
                        ("source_mesh", "<u4"), ("reserved", "<u4", (3,))])
#: An INST record of a two-level file (spec 3.9/3.10): one placement (Scene.instances()); the
#: transforms are affine 3x4 row-major, x_world = M[:, :3] @ x + M[:, 3].
INSTANCE_DTYPE = _np.dtype([("object_to_world", "<f4", (3, 4)), ("world_to_object", "<f4", (3, 4)),
                            ("mesh", "<u4"), ("source_node", "<u4"), ("world_lo", "<f4", (3,)),
                            ("world_hi", "<f4", (3,))])
assert MESH_DTYPE.itemsize == 64 and INSTANCE_DTYPE.itemsize == 128


def compile(inputs, output, threads=None, progress=None, **options):  # noqa: A001 - the verb is the API
    """Compile meshes (glTF/GLB incl. Draco, OBJ, PLY, OFF, STL, DRC) into `output`, as cwbvhc.

    inputs: a path or a list of paths. threads: worker threads (None: all cores; the file is the
    same for any count). options: cwbvhc's options with '_' for '-': builder ('sbvh' | 'embree'),
    collapse ('optimal' | 'greedy'), split_alpha, max_reference_growth, collapse_cost_prim,
    keep_sbvh, keep_mesh, verify, flatten, allow_parent_uris (glTF buffer URIs with '..' may read
    outside the input's folder; refused by default). flatten=False (the default, as cwbvhc) keeps glTF
    instancing (a mesh placed by several nodes): the file is two-level (format 1.2); flatten=True
    (cwbvhc --flatten) places every instance's triangles in one single-level tree (builder
    'embree', keep_sbvh and keep_mesh imply it). progress: optional callable(phase, fraction, seconds), called on
    this thread at each phase's start (0.0, None), every 0.2 s while a counted phase runs, and at
    its end (1.0, seconds). An exception it raises cancels the compile before the next phase and
    propagates: nothing is written and a file already at `output` keeps its bytes (unless raised at
    the write's end, ("write", 1.0, seconds), which comes after the file is in place). Returns the
    statistics of `cwbvhc --stats-json` as a dict (two_level, meshes, instances,
    instanced_triangles, ... for a two-level file). Bad input raises cwbvh.Error with cwbvhc's
    one-line message; bad options raise ValueError/TypeError.
    """
    if isinstance(inputs, (str, bytes)) or hasattr(inputs, "__fspath__"):
        inputs = [inputs]
    elif not hasattr(inputs, "__iter__"):
        raise TypeError("compile: inputs must be a path or a list of paths, got %s" % type(inputs).__name__)
    inputs = [_fspath(p, "compile: inputs") for p in inputs]
    threads = _args.integer(threads, "compile: threads", 1, 4096, none=0)
    if progress is not None and not callable(progress):
        raise TypeError("compile: progress must be callable(phase, fraction, seconds)")
    text = _cwbvh.compile(inputs, _fspath(output, "compile: output"), threads, options, progress)
    return _json.loads(text)


def open(path, deep=False, verify_checksums=True):  # noqa: A001 - cwbvh.open mirrors the loader
    """Map and validate a .cwbvh file (the loader's checks; deep=True adds `cwbvh validate --deep`'s
    containment proof: D1-D4 per tree and, for a two-level file, D7 over the top level: mesh boxes,
    instance world boxes, top-level boxes, scene bounds). Single- and two-level files (format 1.2:
    the MESH, INST and TLAS sections are selected) open alike. Returns a Scene; an invalid file
    raises cwbvh.Error with the message `cwbvh validate` prints. The file is mapped, not read:
    while the Scene is open, do not truncate or rewrite it in place (a read past a truncated end
    kills the process with SIGBUS); replacing it by a rename, as compile() does, is safe."""
    return Scene(_cwbvh.open(_fspath(path, "open: path"), _args.flag(deep, "open: deep"),
                               _args.flag(verify_checksums, "open: verify_checksums")))


class Hits:
    """What Scene.trace returns: t, u, v, prim (views of `records`, the (N, 4) buffer of Hit
    records, without a copy), `instance` and `stats` (rays, hits, nodes_visited, ..., seconds,
    zero_copy; CPU only). Unpacks as ``t, u, v, prim = scene.trace(...)``.

    instance: for a two-level file, the (N,) uint32 INST index of each hit (MISS for a miss;
    Scene.instances()[i] is its placement); None for a single-level file."""

    __slots__ = ("t", "u", "v", "prim", "records", "stats", "instance")

    def __init__(self, t, u, v, prim, records, stats, instance=None):
        self.t, self.u, self.v, self.prim, self.records, self.stats = t, u, v, prim, records, stats
        self.instance = instance

    def __iter__(self):
        return iter((self.t, self.u, self.v, self.prim))

    def __len__(self):
        return len(self.t)

    @property
    def hit(self):
        """Boolean mask of the rays that hit (host results only)."""
        return self.prim != MISS


def _interval(tmin, tmax):
    tmin = 0.0 if tmin is None else _args.number(tmin, "trace: tmin")
    tmax = _math.inf if tmax is None else _args.number(tmax, "trace: tmax")
    if _math.isnan(tmin) or _math.isnan(tmax) or tmin > tmax:
        raise ValueError("tmin and tmax must be numbers with tmin <= tmax, got %r and %r" % (tmin, tmax))
    return tmin, tmax


class Scene:
    """An open .cwbvh file (cwbvh.open). Thread-safe: any number of threads may trace at once.
    close() (or leaving a ``with`` block) releases the Scene's mapping; traces in flight and
    arrays from vertices()/indices() keep it until they end."""

    def __init__(self, handle):
        self._h = handle

    def _handle(self):
        if self._h.closed:
            raise ValueError("%s: the Scene is closed" % self._h.path)
        return self._h

    @property
    def path(self):
        return self._h.path

    @property
    def closed(self):
        return self._h.closed

    @property
    def info(self):
        """Counts, bounds, build statistics (BILD) and sections of the file, as a dict.
        is_two_level; two_level: `cwbvh info --json`'s two-level counts (meshes, instances,
        top_nodes, distinct_triangles, instanced_triangles: the triangles once every instance is
        expanded) for a two-level file, None otherwise. triangles: the stored (distinct) ones."""
        return self._handle().info()

    @property
    def is_two_level(self):
        """True for a two-level file (format 1.2: meshes placed by instances)."""
        return self._handle().is_two_level

    def meshes(self):
        """The bottom levels of a two-level file: (M,) MESH_DTYPE records, read-only, zero-copy
        (empty for a single-level file). prim_first/prim_count: the mesh's stored triangle ids."""
        return self._handle().meshes().view(MESH_DTYPE)[:, 0]

    def instances(self):
        """The placements of a two-level file: (I,) INSTANCE_DTYPE records (object_to_world,
        world_to_object, mesh, source_node = glTF node, world box), read-only, zero-copy; a hit's
        Hits.instance indexes it. Empty for a single-level file."""
        return self._handle().instances().view(INSTANCE_DTYPE)[:, 0]

    def sources(self, prim):
        """Where stored triangles come from (PMAP): (N, 4) uint32 rows (input file, glTF mesh,
        glTF primitive, triangle in that primitive) for the ids `prim` (e.g. Hits.prim); rows of
        MISS for MISS. The same source in a two-level file and its flatten=True twin."""
        ids = _np.asarray(prim)
        if ids.dtype.kind not in "iu":  # 1.9 was read as 1 (a float id is not an id)
            raise TypeError("sources: prim must hold integers, got dtype %s" % ids.dtype)
        if ids.size and (ids.min() < 0 or ids.max() > 0xFFFFFFFF):  # -1 and 2**32 + 5 wrapped
            raise ValueError("sources: prim ids must lie in [0, 2**32 - 1] (MISS = 2**32 - 1)")
        return self._handle().sources(ids.astype(_np.uint32).reshape(-1))

    def vertices(self):
        """The stored mesh's vertices (V, 3) float32, read-only, zero-copy (files compiled with
        keep_mesh=True, which implies flatten; empty otherwise)."""
        return self._handle().vertices()

    def indices(self):
        """The stored mesh's triangles (T, 3) uint32: row i is stored triangle i (a hit's prim)."""
        return self._handle().indices()

    def close(self):
        self._h.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __repr__(self):
        if self.closed:
            state = "closed"
        else:
            info = self.info
            state = "%d nodes" % info["nodes"]
            if info["two_level"]:
                state += ", two-level: %d meshes, %d instances" % (info["two_level"]["meshes"],
                                                                  info["two_level"]["instances"])
        return "<cwbvh.Scene %r (%s)>" % (self.path, state)

    def to_device(self, device=-1):
        """Upload the traversal sections to the GPU once (device -1 or None: the current one; a two-level
        file's top level too). Raises cwbvh.Error when there is no usable GPU (gpu_status() says
        why)."""
        self._handle().to_device(_args.integer(device, "to_device: device", -1, none=-1))
        return self

    @property
    def on_device(self):
        return self._handle().on_device

    def trace(self, origins, directions=None, tmin=None, tmax=None, any_hit=False, watertight=True, threads=None,
              stream=None):
        """Trace rays; returns Hits (t, u, v, prim; and instance for a two-level file).

        origins, directions: float32 arrays (N, 3); or origins alone as (N, 8) rays in the
        ray-file layout (origin, tmin, direction, tmax), which carry their own tmin/tmax.
        tmin, tmax: the interval of (N, 3) rays (default 0 and inf). any_hit: stop at the first
        hit found (occlusion). watertight: Woop et al.'s test (default) or the fast one.
        threads: CPU threads (None: all cores). Host arrays are traced on the CPU without the
        GIL. Device arrays (__cuda_array_interface__ or DLPack: CuPy, PyTorch, Numba, ...) are
        traced on the GPU after to_device(), on `stream` (an int handle or a stream object;
        default: the array's CUDA-array-interface stream, else the legacy default stream), and
        the results are device arrays of the caller's library (DeviceArray otherwise).
        A two-level file runs the two-level traversal (trace_two_level_cpu / trace_two_level) on
        the same inputs, threads and streams: t is in the parameter of the given ray, prim the
        stored id of the triangle hit, Hits.instance the INST index of its instance.
        """
        if self._h.closed:
            raise ValueError("%s: the Scene is closed" % self._h.path)
        packed = directions is None
        o_name = "rays" if packed else "origins"
        if packed and (tmin is not None or tmax is not None):
            raise ValueError("rays (N, 8) carry their own tmin and tmax; pass tmin/tmax only with (N, 3) "
                             "origins and directions")
        tmin, tmax = _interval(tmin, tmax)
        any_hit = _args.flag(any_hit, "trace: any_hit")
        watertight = _args.flag(watertight, "trace: watertight")
        threads = _args.integer(threads, "trace: threads", 1, 1024, none=0)
        stream = _arrays.stream_handle(stream)
        o_dev = _arrays.device_view(origins, o_name, stream)
        d_dev = None if packed else _arrays.device_view(directions, "directions", stream)
        if not packed and (o_dev is None) != (d_dev is None):
            raise TypeError("origins and directions must both be host arrays or both device arrays")
        if o_dev is not None:
            return self._trace_device(origins, o_dev, d_dev, tmin, tmax, any_hit, watertight, stream)
        o = _arrays.host_array(origins, o_name)
        d = None if packed else _arrays.host_array(directions, "directions")
        stats = {}
        records, instance = self._h.trace_host(o, d, tmin, tmax, any_hit, watertight, threads, stats)
        return Hits(records[:, 0], records[:, 1], records[:, 2], records.view(_np.uint32)[:, 3], records, stats,
                    instance)

    def _trace_device(self, reference, o, d, tmin, tmax, any_hit, watertight, stream):
        _arrays.check_device_rays(o, "origins" if d is not None else "rays", 3 if d is not None else 8)
        if d is not None:
            _arrays.check_device_rays(d, "directions", 3)
            if d.shape[0] != o.shape[0]:
                raise ValueError("origins and directions differ in length: %d vs %d" % (o.shape[0], d.shape[0]))
        if not self._h.on_device:
            raise ValueError("%s: the Scene is not on the GPU: call Scene.to_device() first" % self.path)
        if stream is None:
            stream = o.stream if o.stream is not None else _arrays.LEGACY_DEFAULT_STREAM
        n = o.shape[0]
        def row_stride(view, cols):  # a single row's stride is arbitrary (often 0): any value >= its width works
            return view.strides[0] if view.shape[0] > 1 else 4 * cols

        buf = self._h.trace_device(o.ptr, row_stride(o, 8 if d is None else 3), 0 if d is None else d.ptr,
                                   0 if d is None else row_stride(d, 3), n, tmin, tmax, stream, bool(any_hit),
                                   bool(watertight))
        del o, d  # the inputs' capsules/objects may go: the work is ordered on `stream`
        device = self._h.device_id

        def column(offset, typestr):
            a = _arrays.DeviceArray(buf, buf.ptr + offset, (n,), (16,), typestr, device, stream)
            return _arrays.like(a, reference)

        records = _arrays.like(_arrays.DeviceArray(buf, buf.ptr, (n, 4), (16, 4), "<f4", device, stream), reference)
        instance = None
        if self._h.is_two_level:  # the n INST indices follow the n Hit records (device_trace.cpp)
            instance = _arrays.like(_arrays.DeviceArray(buf, buf.ptr + 16 * n, (n,), (4,), "<u4", device, stream),
                                    reference)
        return Hits(column(0, "<f4"), column(4, "<f4"), column(8, "<f4"), column(12, "<u4"), records, {}, instance)
