"""The walls of a single-quad room with a skylight under every bundled HDRI: the view against api.shade's model, traced light and Cycles.

    .venv/bin/python benchmarks/wide_walls_report.py [--root PATH] [--hdris a,b] [--samples 128]

The room is tests/helpers/skylight_quads.py's (floor, four walls and a ceiling with a 1 x 1 m
skylight, one quad each, a table top and a box), baked with the Good preset's order and
directions without bounces, so that Cycles' DIFFUSE bake with the DIRECT pass (sky and lights,
no bounce) is the reference. Per wall, over the grid points the camera sees:
  view: the drawn radiance (render_view, white albedo), lights: its split-light part;
  shade: api.shade's model at the same points (the view's SH part plus the lights traced with
  one ray per sample, 16 per light); dense: the lights traced over 1024 power cells per light;
  cycles: Cycles' DIRECT bake of the wall into its own 0..1 UV square (32 x 32 texels).
Printed: per HDRI and wall the mean of view / shade / Cycles, RMS of view and shade against
Cycles (relative to Cycles' RMS), RMS of the view's and api.shade's split-light part against
the dense trace (relative to its RMS), and the second differences of the view's split-light part
along the wall over the dense trace's (helpers.skylight_quads.second_differences: 1 is as smooth
as the trace, streaks and steps add to it). --root: run another checkout's add-on (e.g. main, before).
"""

import argparse
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
HDRIS = ("city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset")
CYCLES_WALLS = ("back", "right", "left", "floor")
TEXELS = 32


def _unit_square_uvs(obj):
    layer = obj.data.uv_layers.new(name="Square")
    layer.uv.foreach_set("vector", np.tile([0, 0, 1, 0, 1, 1, 0, 1], len(obj.data.polygons)).astype(np.float32))
    return layer.name


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--root", default=HERE)
    parser.add_argument("--hdris", default=",".join(HDRIS))
    parser.add_argument("--samples", type=int, default=128)
    args = parser.parse_args()
    sys.path.insert(0, os.path.abspath(args.root))
    sys.path.insert(0, os.path.join(HERE, "tests"))
    import bpy
    from helpers import skylight_quads as room
    from helpers.texel_scenes import cycles_texel_bake

    import prt_addon
    from prt_addon import api
    from prt_addon.blender.display import offscreen
    from prt_addon.blender.scene import lighting

    prt_addon.register()
    assert offscreen.ensure_gpu()
    print(
        "| HDRI | wall | mean view / api.shade / Cycles | view vs Cycles | api.shade vs Cycles | lights: view vs traced | api.shade vs traced "
        "| second differences: view / traced |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for hdri in args.hdris.split(","):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = bpy.context.scene
        objects = room.build(bpy, scene, hdri)
        api.bake(objects, order=4, samples=256)
        api.project_world(scene, 4, split_lights=True)
        lights = lighting.world_lights(scene)
        image = api.render_view(scene, room.SIZE, room.SIZE)
        lighting.set_lights_override(scene, [])
        sky = api.render_view(scene, room.SIZE, room.SIZE)
        lighting.set_lights_override(scene, None)
        dense = room.dense_lights(scene, lights) if lights else []
        walls = room.wall_samples(bpy, scene, image, sky, lights, dense)
        targets = [bpy.data.objects[name] for name in CYCLES_WALLS]
        uv = {obj.name: _unit_square_uvs(obj) for obj in targets}
        baked = cycles_texel_bake(bpy, scene, targets, TEXELS, args.samples, uv_name=uv[targets[0].name])
        for name in room.WALLS:
            w = walls[name]
            shade = w["total"] - w["view"] + w["shade"]
            if name in baked:
                i, j = w["grid"]
                u = (0.03 + 0.94 * i / (room.GRID - 1)) * TEXELS
                v = (0.03 + 0.94 * j / (room.GRID - 1)) * TEXELS
                cycles = (
                    baked[name][np.minimum(v.astype(int), TEXELS - 1), np.minimum(u.astype(int), TEXELS - 1)]
                    @ room.LUMA
                )
                means = f"{w['total'].mean():.4f} / {shade.mean():.4f} / {cycles.mean():.4f}"
                against = f"{100 * room.relative_rms(w['total'], cycles):.1f} % | {100 * room.relative_rms(shade, cycles):.1f} %"
            else:
                means = f"{w['total'].mean():.4f} / {shade.mean():.4f} / -"
                against = "- | -"
            if lights and np.sqrt(np.mean(w["dense"] ** 2)) > 0.02 * w["total"].mean():
                traced = f"{100 * room.relative_rms(w['view'], w['dense']):.0f} % | {100 * room.relative_rms(w['shade'], w['dense']):.0f} %"
                traced += f" | {room.second_differences(w, 'view') / room.second_differences(w, 'dense'):.2f}"
            else:
                traced = f"({w['view'].mean():.5f} / {w['dense'].mean():.5f}) | - | -"
            print(f"| {hdri} | {name} | {means} | {against} | {traced} |", flush=True)
    prt_addon.unregister()


if __name__ == "__main__":
    main()
