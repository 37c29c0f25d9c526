"""The examples (examples/python/) run on a shared scene and write their PNGs."""

import os
import subprocess
import sys

import pytest

from conftest import SCENES_DIR, SHARED_SCENE, SOURCE_DIR, require


@pytest.mark.parametrize("script", ["depth_image.py", "lidar_scan.py"])
def test_example_writes_png(tmp_path, script, shared_file):
    require(SCENES_DIR / SHARED_SCENE, "shared scene")
    out = tmp_path / (script[:-3] + ".png")
    env = dict(os.environ, MPLBACKEND="Agg", MPLCONFIGDIR=str(tmp_path))
    subprocess.run([sys.executable, str(SOURCE_DIR / "examples" / "python" / script), str(shared_file), "-o", str(out)],
                   check=True, env=env, capture_output=True)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
