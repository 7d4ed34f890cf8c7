"""Accuracy of the Principled specular: render_view, the diffuse-only draw and EEVEE against Cycles with
direct light only (0 bounces), per object, on tests/helpers/specular_scenes.py's spheres under city.exr.

    .venv/bin/python benchmarks/accuracy_specular.py [--samples 128] [--eevee-samples 16]

The reference is the mean of two Cycles renders with different seeds; its noise is their
difference's relative RMSE over 2 (the mean's). Relative RMSE of luminance per object
(docs/specular.md).
"""

import argparse
import os
import sys
import time

root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path.insert(0, root)
sys.path.insert(0, os.path.join(root, "tests"))

import bpy
import numpy as np
from helpers import specular_scenes as ss

import prt_addon
from prt_addon import api
from prt_addon.blender.display import offscreen


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--samples", type=int, default=128)
    parser.add_argument("--eevee-samples", type=int, default=16)
    parser.add_argument("--order", type=int, default=8)
    args = parser.parse_args()
    prt_addon.register()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    offscreen.ensure_gpu()
    spheres, ground, _cam = ss.spheres_scene(bpy, scene)
    api.project_world(scene, order=args.order, split_lights=True)
    api.bake([*spheres.values(), ground], order=args.order, samples=512)
    masks = ss.object_masks(bpy, scene, {**spheres, "ground": ground})
    scene.prt_display.specular = False
    diffuse = offscreen.render_view(scene)[..., :3].astype(np.float64)
    scene.prt_display.specular = True
    prt = offscreen.render_view(scene)[..., :3].astype(np.float64)
    start = time.perf_counter()
    first = ss.cycles_render(bpy, scene, args.samples, seed=0)
    second = ss.cycles_render(bpy, scene, args.samples, seed=1)
    cycles_seconds = (time.perf_counter() - start) / 2
    start = time.perf_counter()
    try:
        eevee = ss.eevee_render(bpy, scene, args.eevee_samples)
    except RuntimeError as error:
        eevee = None
        print(f"EEVEE did not render: {error}")
    eevee_seconds = time.perf_counter() - start
    reference = 0.5 * (first + second)
    print(f"Cycles {args.samples} samples: {cycles_seconds:.1f} s a render; EEVEE {eevee_seconds:.1f} s")
    print("| object | PRT | diffuse only | EEVEE | PRT / EEVEE | Cycles noise |")
    print("|---|---|---|---|---|---|")
    for name, mask in masks.items():
        error = ss.relative_rmse(prt, reference, mask)
        before = ss.relative_rmse(diffuse, reference, mask)
        noise = ss.relative_rmse(first, second, mask) / 2.0
        ee = ss.relative_rmse(eevee, reference, mask) if eevee is not None else float("nan")
        print(f"| {name} | {error:.1%} | {before:.1%} | {ee:.1%} | {error / ee:.2f} | {noise:.1%} |")


if __name__ == "__main__":
    main()
