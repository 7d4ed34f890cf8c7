"""Interreflected texel bakes: the time of 1 and 3 bounces against the direct bake (every texel traced) of the low-poly room, side by side.

Run after the test command has made the venv:  .venv/bin/python benchmarks/bench_texel_bounces.py
(--resolution 32 --samples 256 --repeats 3). Each ratio is the median of --repeats runs, each run
baking direct, 1 and 3 bounces one after the other (2-core figures are noisy).
"""

import argparse
import os
import statistics
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))

import bpy
import numpy as np

import prt_addon
from prt_addon import api
from prt_addon.blender.scene import lighting

SKY = np.zeros((64, 3))
SKY[0] = np.sqrt(4.0 * np.pi)
SKY[2] = 1.0


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", type=int, default=32)
    parser.add_argument("--samples", type=int, default=256)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    from helpers import texel_scenes

    prt_addon.register()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    objs = texel_scenes.low_poly_room(bpy)
    lighting.set_light_override(bpy.context.scene, SKY)
    options = {"order": 8, "samples": args.samples, "target": "TEXELS", "resolution": args.resolution}
    options.update(uv_map=texel_scenes.LIGHTMAP, adaptive=0.0)
    ratios = {1: [], 3: []}
    seconds = {0: [], 1: [], 3: []}
    for _ in range(args.repeats):
        for bounces in (0, 1, 3):
            started = time.perf_counter()
            api.bake(objs, bounces=bounces, **options)
            seconds[bounces].append(time.perf_counter() - started)
        for bounces in (1, 3):
            ratios[bounces].append(seconds[bounces][-1] / seconds[0][-1])
    print(
        f"low-poly room, {len(objs)} objects, {args.resolution} x {args.resolution} texels, order 8, {args.samples} directions"
    )
    print(f"direct: {statistics.median(seconds[0]):.3f} s")
    for bounces in (1, 3):
        print(
            f"{bounces} bounce(s): {statistics.median(seconds[bounces]):.3f} s, {statistics.median(ratios[bounces]):.2f} x direct"
        )


if __name__ == "__main__":
    main()
