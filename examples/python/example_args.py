"""Command line of the examples: SCENE (a .cwbvh file, or a mesh compiled once next to the
output; default ../shared/scenes/sponza_dabrovic.glb), --view NAME and -o PNG. Not part of the
user code each example shows."""
import argparse
import pathlib

import cwbvh

DEFAULT_SCENE = pathlib.Path(__file__).resolve().parents[3] / "shared" / "scenes" / "sponza_dabrovic.glb"


def parse(default_output):
    """(args, path of the .cwbvh file to open)."""
    ap = argparse.ArgumentParser()
    ap.add_argument("scene", nargs="?", default=str(DEFAULT_SCENE))
    ap.add_argument("--view", default=None, help="a view of views/catalog.txt (default: the scene's first)")
    ap.add_argument("-o", "--output", default=default_output)
    args = ap.parse_args()
    path = pathlib.Path(args.scene)
    if path.suffix != ".cwbvh":
        path = pathlib.Path(args.output).with_name(path.stem + ".cwbvh")
        if not path.exists():
            cwbvh.compile(args.scene, path)
    return args, path
