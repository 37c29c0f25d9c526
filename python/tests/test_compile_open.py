"""cwbvh.compile (cwbvhc's options, statistics, progress, errors with cwbvhc's one line) and
cwbvh.open (validation with `cwbvh validate`'s message, deep validation, info)."""

import json
import subprocess

import pytest

import cwbvh
from conftest import BUNNY_OBJ, require, run, tool


def test_compile_matches_cwbvhc(tmp_path):
    obj = require(BUNNY_OBJ, "the bunny")
    stats = cwbvh.compile([str(obj)], tmp_path / "py.cwbvh", threads=1, split_alpha=1e-4, collapse="greedy")
    run(tool("cwbvhc"), obj, "-o", tmp_path / "tool.cwbvh", "--threads", "2", "--split-alpha", "1e-4",
        "--collapse", "greedy", "--stats-json", tmp_path / "stats.json", "--quiet")
    assert (tmp_path / "py.cwbvh").read_bytes() == (tmp_path / "tool.cwbvh").read_bytes()
    tool_stats = json.loads((tmp_path / "stats.json").read_text())
    assert set(stats) == set(tool_stats)
    for key in ("triangles", "references", "wide_nodes", "sah_wide", "file_bytes"):
        assert stats[key] == tool_stats[key]


def test_progress_callback(tmp_path):
    events = []
    cwbvh.compile(str(require(BUNNY_OBJ, "the bunny")), tmp_path / "b.cwbvh",
                  progress=lambda phase, fraction, seconds: events.append((phase, fraction, seconds)))
    phases = [p for p, f, s in events if s is not None]
    assert phases[0] == "import" and phases[-1] == "write" and "sbvh" in phases
    assert all(0.0 <= f <= 1.0 for _, f, _ in events)
    assert all(f == 1.0 and s >= 0 for _, f, s in events if s is not None)


class Stop(Exception):
    pass


def test_progress_exception_is_raised(tmp_path):
    def boom(*_):
        raise Stop()

    with pytest.raises(Stop):
        cwbvh.compile(str(require(BUNNY_OBJ, "the bunny")), tmp_path / "b.cwbvh", progress=boom)
    assert not (tmp_path / "b.cwbvh").exists()


def test_progress_exception_cancels_the_compile(tmp_path):
    """An exception of the callback at any phase start or end before the write's end stops the
    compile there: it propagates, no later phase is reported, no file is written and a file
    already at the output path keeps its bytes (it was raised only after the write)."""
    n = 24
    lines = ["v %d %d %g" % (x, y, 0.3 * (x % 3)) for y in range(n + 1) for x in range(n + 1)]
    for y in range(n):
        for x in range(n):
            a = y * (n + 1) + x + 1
            lines += ["f %d %d %d" % (a, a + 1, a + n + 2), "f %d %d %d" % (a, a + n + 2, a + n + 1)]
    src = tmp_path / "grid.obj"
    src.write_text("\n".join(lines) + "\n")
    boundaries = []
    cwbvh.compile(src, tmp_path / "full.cwbvh", progress=lambda p, f, s: boundaries.append((p, f, s is not None))
                  if (f, s is not None) in ((0.0, False), (1.0, True)) else None)
    assert boundaries[0] == ("import", 0.0, False) and boundaries[-1] == ("write", 1.0, True)
    out = tmp_path / "out.cwbvh"
    for at in boundaries[:-1]:
        for existing in (False, True):
            if existing:
                out.write_bytes(b"the file that was there before")
            elif out.exists():
                out.unlink()
            seen = []

            def progress(phase, fraction, seconds):
                seen.append((phase, fraction, seconds is not None))
                if seen[-1] == at:
                    raise Stop(at)

            with pytest.raises(Stop):
                cwbvh.compile(src, out, progress=progress)
            assert seen[-1] == at, (at, seen)
            if existing:
                assert out.read_bytes() == b"the file that was there before", at
            else:
                assert not out.exists(), at
            assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
                ["grid.obj", "full.cwbvh"] + (["out.cwbvh"] if existing else [])), at


def cwbvhc_error(*args):
    p = subprocess.run([tool("cwbvhc"), *map(str, args)], capture_output=True, text=True)
    assert p.returncode == 1
    line = p.stderr.strip().splitlines()[-1]
    assert line.startswith("cwbvhc: error: ")
    return line[len("cwbvhc: error: "):]


@pytest.mark.parametrize("content", [None, "v 0 0 0\nf 1 2 3\n", "this is not a mesh\n"])
def test_compile_errors_carry_cwbvhc_message(tmp_path, content):
    src = tmp_path / "bad.obj"
    if content is not None:
        src.write_text(content)
    with pytest.raises(cwbvh.Error) as e:
        cwbvh.compile(src, tmp_path / "out.cwbvh")
    assert str(e.value) == cwbvhc_error(src, "-o", tmp_path / "out2.cwbvh")
    assert "\n" not in str(e.value) and str(src) in str(e.value)
    assert isinstance(e.value, RuntimeError) and e.value.status


def test_compile_refuses_to_overwrite_an_input(tmp_path):
    src = tmp_path / "mesh.obj"
    src.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    before = src.read_bytes()
    for out in (src, tmp_path / "." / "mesh.obj", tmp_path):
        with pytest.raises(cwbvh.Error) as e:
            cwbvh.compile(src, out)
        assert str(e.value) == cwbvhc_error(src, "-o", out) and e.value.status == "invalid argument"
    assert src.read_bytes() == before


def test_compile_option_errors(tmp_path):
    with pytest.raises(TypeError, match="unexpected option 'alpha'"):
        cwbvh.compile("x.obj", tmp_path / "o.cwbvh", alpha=1)
    with pytest.raises(ValueError, match="split_alpha"):
        cwbvh.compile("x.obj", tmp_path / "o.cwbvh", split_alpha=2.0)
    with pytest.raises(ValueError, match="builder"):
        cwbvh.compile("x.obj", tmp_path / "o.cwbvh", builder="lbvh")
    with pytest.raises(ValueError, match="threads"):
        cwbvh.compile("x.obj", tmp_path / "o.cwbvh", threads=0)
    with pytest.raises(TypeError, match="progress"):
        cwbvh.compile("x.obj", tmp_path / "o.cwbvh", progress=3)


def test_compile_allow_parent_uris(tmp_path):
    # One triangle whose buffer lies one folder up ("../tri.bin"): refused by default, as by
    # cwbvhc, and read with allow_parent_uris=True (cwbvhc --allow-parent-uris).
    import json, struct
    (tmp_path / "tri.bin").write_bytes(struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0))
    (tmp_path / "sub").mkdir()
    src = tmp_path / "sub" / "tri.gltf"
    src.write_text(json.dumps({
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "buffers": [{"uri": "../tri.bin", "byteLength": 36}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]}]}))
    with pytest.raises(cwbvh.Error, match=r"\.\."):
        cwbvh.compile(src, tmp_path / "refused.cwbvh")
    assert not (tmp_path / "refused.cwbvh").exists()
    stats = cwbvh.compile(src, tmp_path / "ok.cwbvh", allow_parent_uris=True)
    assert stats["triangles"] == 1
    with pytest.raises(TypeError, match="allow_parent_uris"):
        cwbvh.compile(src, tmp_path / "o.cwbvh", parent_uris=True)


def test_open_info_and_deep(bunny_file):
    with cwbvh.open(bunny_file, deep=True) as scene:
        info = scene.info
        assert info["triangles"] == 69666 and info["nodes"] > 0 and info["has_mesh"]
        assert info["build"]["wide_nodes"] == info["nodes"] and info["build"]["builder"] == "sbvh"
        lo, hi = info["bounds"]
        assert lo[0] == -1.0 and hi[0] == 1.0
        assert [s for s, _ in info["sections"]][:3] == ["NODE", "TRIS", "PMAP"]
        assert scene.indices().shape == (69666, 3)


def test_open_errors_carry_validate_message(bunny_file, tmp_path):
    bad = tmp_path / "corrupt.cwbvh"
    data = bytearray(bunny_file.read_bytes())
    data[len(data) // 2] ^= 0xFF  # a payload byte: checksum mismatch
    bad.write_bytes(data)
    for path in (bad, tmp_path / "missing.cwbvh", tmp_path):
        with pytest.raises(cwbvh.Error) as e:
            cwbvh.open(path)
        p = subprocess.run([tool("cwbvh"), "validate", str(path)], capture_output=True, text=True)
        assert p.returncode == 1 and p.stderr.strip().endswith(str(e.value))
    # without checksums the flipped byte may pass the structural checks or not, but never crash
    try:
        cwbvh.open(bad, verify_checksums=False, deep=True).close()
    except cwbvh.Error:
        pass
