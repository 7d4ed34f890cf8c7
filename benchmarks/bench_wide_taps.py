"""Frame cost of the wide lights' filter taps: the skylight room under an HDRI, maps cached, variants side by side.

    .venv/bin/python benchmarks/bench_wide_taps.py [--hdri courtyard] [--frames 9] [--variants 8/8/6,24/8/6]

The room of tests/helpers/skylight_quads.py (order 2 bake; courtyard splits off three wide lights
and a compact one), drawn by display.draw_objects into a 512 x 512 RGBA32F offscreen with the
shadow maps cached (drawn once), each frame synchronised by a one-pixel read-back. A variant is
"PCF taps/first taps/blocker taps" of the wide lights' views (display/shader_suns.py's
WIDE_PCF_TAPS, WIDE_FIRST_TAPS and WIDE_BLOCKER_TAPS; 8/8/6 is the filter before the first taps),
each compiled once; "PRT only" draws the room without its split lights. All
variants are interleaved frame by frame; printed: the median, its range and the ratio to the
first variant. llvmpipe timings are noisy on shared cores: compare ratios within one run.
"""

import argparse
import os
import statistics
import sys
import time

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "tests"))

import bpy
import gpu
import mathutils
from helpers import skylight_quads as room

import prt_addon
from prt_addon import api
from prt_addon.blender.display import draw as display_draw, offscreen, shader, shader_suns
from prt_addon.blender.scene import lighting


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--hdri", default="courtyard")
    parser.add_argument("--frames", type=int, default=9)
    parser.add_argument(
        "--variants",
        default=f"8/8/6,{shader_suns.WIDE_PCF_TAPS}/{shader_suns.WIDE_FIRST_TAPS}/{shader_suns.WIDE_BLOCKER_TAPS}",
    )
    args = parser.parse_args()
    prt_addon.register()
    assert offscreen.ensure_gpu()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    objects = room.build(bpy, scene, args.hdri)
    api.bake(objects, order=2, samples=64)
    api.project_world(scene, 2, split_lights=True)
    lights = lighting.world_lights(scene)
    view, proj = offscreen.camera_matrices(scene, room.SIZE, room.SIZE)
    vp = mathutils.Matrix((proj @ view).tolist())
    variants = [("PRT only", None)] + [(f"taps {v}", tuple(map(int, v.split("/")))) for v in args.variants.split(",")]
    compiled = {name: {} for name, _ in variants}  # each variant's shaders
    times = {name: [] for name, _ in variants}
    print(f"renderer: {gpu.platform.renderer_get()}; {room.SIZE} x {room.SIZE}; {args.hdri}: {len(lights)} lights")
    off = gpu.types.GPUOffScreen(room.SIZE, room.SIZE, format="RGBA32F")
    with off.bind():
        fb = gpu.state.active_framebuffer_get()
        gpu.state.depth_test_set("LESS_EQUAL")
        gpu.state.depth_mask_set(True)
        for frame in range(args.frames + 1):
            for name, taps in variants:
                lighting.set_lights_override(scene, [] if taps is None else None)
                if taps is not None:
                    shader_suns.WIDE_PCF_TAPS, shader_suns.WIDE_FIRST_TAPS, shader_suns.WIDE_BLOCKER_TAPS = taps
                shader._shaders.clear()
                shader._shaders.update(compiled[name])
                fb.clear(color=(0, 0, 0, 0), depth=1.0)
                t0 = time.perf_counter()
                display_draw.draw_objects(scene, vp, objects)
                fb.read_color(room.SIZE // 2, room.SIZE // 2, 1, 1, 4, 0, "FLOAT")
                if frame:  # frame 0 compiles and draws the maps
                    times[name].append(time.perf_counter() - t0)
                compiled[name] = dict(shader._shaders)
        gpu.state.depth_test_set("NONE")
    off.free()
    lighting.set_lights_override(scene, None)
    first = statistics.median(times[variants[1][0]])
    print(f"{'variant':<14} {'median ms':>10} {'range ms':>16} {'/ ' + variants[1][0]:>14}")
    for name, _ in variants:
        t = times[name]
        print(
            f"{name:<14} {statistics.median(t) * 1e3:>10.1f} {min(t) * 1e3:>7.1f} .. {max(t) * 1e3:<6.1f} "
            f"{statistics.median(t) / first:>14.2f}"
        )
    prt_addon.unregister()


if __name__ == "__main__":
    main()
