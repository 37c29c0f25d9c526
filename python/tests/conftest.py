"""Fixtures of the Python tests: the build tree's tools (CWBVH_BIN_DIR, set by ctest), the bunny
(Debian glmark2-data) and a shared scene (CWBVH_SHARED_SCENES_DIR, ../shared/scenes from the
repository): absent inputs skip, unless CI=true, where they fail."""

import os
import pathlib
import subprocess
import threading
import time

import pytest

import cwbvh

SOURCE_DIR = pathlib.Path(os.environ.get("CWBVH_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
BIN_DIR = pathlib.Path(os.environ.get("CWBVH_BIN_DIR", SOURCE_DIR / "build" / "bin"))
SCENES_DIR = pathlib.Path(os.environ.get("CWBVH_SHARED_SCENES_DIR", SOURCE_DIR.parent / "shared" / "scenes"))
BUNNY_OBJ = pathlib.Path("/usr/share/glmark2/models/bunny.obj")
SHARED_SCENE = "sponza_dabrovic.glb"  # 66k triangles, enclosed, three catalog views


def require(path, what):
    if path.exists():
        return path
    message = "%s not found: %s" % (what, path)
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(message + " (CI=true: required)")
    pytest.skip(message)


def ticks_while(fn):
    """Runs fn() while another thread appends a time stamp every millisecond; returns
    (seconds fn took, stamps taken while it ran). Few stamps mean fn held the GIL."""
    ticks, done = [], threading.Event()

    def ticker():
        while not done.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    th = threading.Thread(target=ticker)
    th.start()
    start = time.perf_counter()
    fn()
    end = time.perf_counter()
    done.set()
    th.join()
    return end - start, [t for t in ticks if start < t < end]


def tool(name):
    return str(require(BIN_DIR / name, "the %s tool of the build tree (CWBVH_BIN_DIR)" % name))


def run(*args):
    return subprocess.run([str(a) for a in args], check=True, capture_output=True, text=True).stdout


@pytest.fixture(scope="session")
def bunny_file(tmp_path_factory):
    out = tmp_path_factory.mktemp("bunny") / "bunny.cwbvh"
    cwbvh.compile(str(require(BUNNY_OBJ, "the bunny (Debian glmark2-data)")), out, keep_mesh=True)
    return out


@pytest.fixture(scope="session")
def shared_file(tmp_path_factory):
    src = require(SCENES_DIR / SHARED_SCENE, "shared scene")
    out = tmp_path_factory.mktemp("shared") / (src.stem + ".cwbvh")
    cwbvh.compile(str(src), out)
    return out


@pytest.fixture
def bunny(bunny_file):
    with cwbvh.open(bunny_file) as scene:
        yield scene
