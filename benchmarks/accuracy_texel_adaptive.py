"""Adaptive texel sampling against Cycles: rays traced and error at several tolerances, beside tracing every texel at 256, 128 and 64 directions.

Run from the repository root:  .venv/bin/python benchmarks/accuracy_texel_adaptive.py RES [TOL ...]
The low-poly room of tests/helpers/texel_scenes.py under sunset.exr (the sun split off), order 8;
Cycles' DIFFUSE/DIRECT image bake at 128 samples with seeds 0 and 1 (their difference is its
noise; the bakes are compared with their mean); relative RMSE of luminance over covered texels.
"""

import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))

import bpy
from helpers import texel_scenes as ts
from helpers.worlds import bundled_hdri_path

import prt_addon
from prt_addon import api


def sunset_room():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    world = bpy.data.worlds.new("Sunset")
    scene.world = world
    world.use_nodes = True
    env = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(bundled_hdri_path("sunset"))
    world.node_tree.links.new(env.outputs["Color"], world.node_tree.nodes["Background"].inputs["Color"])
    return scene, ts.low_poly_room(bpy)


def main():
    prt_addon.register()
    res, tolerances = int(sys.argv[1]), [float(t) for t in sys.argv[2:]] or [0.05]
    scene, objs = sunset_room()
    cycles = [ts.cycles_texel_bake(bpy, scene, objs, res, 128, seed=seed) for seed in (0, 1)]
    masks = {o.name: ts.interior_texels(o, res) for o in objs}
    mean = {n: 0.5 * (cycles[0][n] + cycles[1][n]) for n in masks}
    print(f"{res} x {res}: Cycles seed 0 against seed 1 {100 * ts.relative_rmse(cycles[0], cycles[1], masks):.2f} %")
    api.project_world(scene, order=8, split_lights=True)
    full = None
    for samples, tol in [(256, 0.0), (128, 0.0), (64, 0.0)] + [(256, t) for t in tolerances]:
        t0 = time.perf_counter()
        report = api.bake(
            objs, order=8, samples=samples, target="TEXELS", resolution=res, uv_map=ts.LIGHTMAP, adaptive=tol
        )
        seconds = time.perf_counter() - t0
        ours = {o.name: api.shade(o) for o in objs}
        full = full or ours
        print(
            f"  {samples} directions, adaptive {tol:<5}: rays {report.rays_traced:>10,} ({seconds:.2f} s), "
            f"{report.texels_interpolated:,} of {report.texels:,} texels interpolated; against Cycles "
            f"{100 * ts.relative_rmse(ours, mean, masks):.2f} %, against every texel at 256 "
            f"{100 * ts.relative_rmse(ours, full, masks):.2f} %"
        )


if __name__ == "__main__":
    main()
