"""The split-light part of a single-quad room's view under courtyard.exr, to compare the joins before and after a change.

    .venv/bin/python benchmarks/join_lines_figure.py OUT.npy [--root PATH]
    .venv/bin/python benchmarks/join_lines_figure.py --panels BEFORE.npy AFTER.npy OUT.png

The room is tests/helpers/skylight_quads.py's, baked at order 2 (the lights' part does not depend
on the bake), drawn by render_view with courtyard's split lights and with none; the difference's
luminance is saved. --panels puts two of them side by side, as sqrt(part / 0.05) (docs/display.md,
"Joins"). --root: run another checkout's add-on (e.g. main, before).
"""

import argparse
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _panels(before, after, out):
    from PIL import Image

    parts = [np.clip(np.sqrt(np.maximum(np.load(p), 0.0) / 0.05), 0.0, 1.0) for p in (before, after)]
    gap = np.ones((parts[0].shape[0], 8))
    Image.fromarray((np.hstack([parts[0], gap, parts[1]]) * 255).astype(np.uint8)).save(out)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("out", nargs="?")
    parser.add_argument("--root", default=HERE)
    parser.add_argument("--panels", nargs=3)
    args = parser.parse_args()
    if args.panels:
        _panels(*args.panels)
        return
    sys.path.insert(0, os.path.abspath(args.root))
    sys.path.insert(0, os.path.join(HERE, "tests"))
    import bpy
    from helpers import skylight_quads as room

    import prt_addon
    from prt_addon import api
    from prt_addon.blender.display import offscreen
    from prt_addon.blender.scene import lighting

    prt_addon.register()
    assert offscreen.ensure_gpu()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    api.bake(room.build(bpy, scene, "courtyard"), order=2, samples=64)
    api.project_world(scene, 2, split_lights=True)
    image = api.render_view(scene, room.SIZE, room.SIZE)
    lighting.set_lights_override(scene, [])
    sky = api.render_view(scene, room.SIZE, room.SIZE)
    lighting.set_lights_override(scene, None)
    np.save(args.out, (image[..., :3] - sky[..., :3]) @ room.LUMA)
    prt_addon.unregister()


if __name__ == "__main__":
    main()
