"""Texel specular benchmark: the frame of the texel-baked room with glossy materials, with the texel bakes' specular occlusion against the same specular without it, and diffuse only.

    .venv/bin/python benchmarks/bench_texel_specular.py [--resolution 64] [--frames 15] [--size 512]

The low-poly room of tests/helpers/texel_scenes.py (every object per texel at `resolution`, a
glossy metal Principled material) under a sunny sky, drawn offscreen from inside; the three
shaders are compiled once and drawn in turn frame by frame (each frame synchronised by reading a
pixel back). Prints each variant's median frame and range, and the medians of the per-round
ratios with their ranges, and the load average: ratios are what to read (llvmpipe, shared cores).
"""

import argparse
import math
import os
import statistics
import sys
import time

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, ".."))
sys.path.insert(0, os.path.join(here, "..", "tests"))

import bpy
import gpu
import mathutils
from helpers import texel_scenes
from helpers.specular_scenes import principled_material
from helpers.texel_glossy_scene import without_texel_occlusion
from helpers.worlds import image_world, sunny_image

import prt_addon
from prt_addon import api
from prt_addon.blender.display import draw as display_draw, offscreen, shader


def compiled(scene, objects, mvp, fb, specular):
    """The shader cache after one frame drawn (the shaders that frame compiled)."""
    shader.clear_shaders()
    scene.prt_display.specular = specular
    fb.clear(color=(0, 0, 0, 0), depth=1.0)
    display_draw.draw_objects(scene, mvp, objects)
    return dict(shader._shaders)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--resolution", type=int, default=64)
    parser.add_argument("--frames", type=int, default=15)
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--orders", type=int, nargs="+", default=[4, 8])
    args = parser.parse_args()

    bpy.ops.wm.read_factory_settings(use_empty=True)
    prt_addon.register()
    assert offscreen.ensure_gpu()
    scene = bpy.context.scene
    objects = texel_scenes.low_poly_room(bpy)
    for obj in objects:
        obj.data.materials.append(principled_material(bpy, obj.name, (0.8, 0.8, 0.8), 0.3, 1.0))
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    cam.location = (1.7, -1.8, 1.4)
    cam.rotation_euler = (math.radians(70.0), 0.0, math.radians(40.0))
    scene.camera = cam
    image_world(bpy, scene, sunny_image(256, 512), euler=(0.0, 0.0, 0.3))
    view, proj = offscreen.camera_matrices(scene, args.size, args.size)
    mvp = mathutils.Matrix((proj @ view).tolist())
    print(f"renderer: {gpu.platform.renderer_get()}; load average {os.getloadavg()}")
    size = args.size
    for order in args.orders:
        api.project_world(scene, order=order)
        api.bake(
            objects, order=order, samples=64, target="TEXELS", uv_map=texel_scenes.LIGHTMAP, resolution=args.resolution
        )
        off = gpu.types.GPUOffScreen(size, size, format="RGBA32F")
        with off.bind():
            fb = gpu.state.active_framebuffer_get()
            gpu.state.depth_test_set("LESS_EQUAL")
            gpu.state.depth_mask_set(True)
            caches = {"diffuse": (False, compiled(scene, objects, mvp, fb, False))}
            with without_texel_occlusion():
                caches["specular, no occlusion"] = (True, compiled(scene, objects, mvp, fb, True))
            caches["specular, occlusion"] = (True, compiled(scene, objects, mvp, fb, True))
            times = {name: [] for name in caches}

            def frame(name):
                scene.prt_display.specular, shader._shaders = caches[name]
                fb.clear(color=(0, 0, 0, 0), depth=1.0)
                t0 = time.perf_counter()
                display_draw.draw_objects(scene, mvp, objects)
                fb.read_color(size // 2, size // 2, 1, 1, 4, 0, "FLOAT")  # wait for the GPU
                return time.perf_counter() - t0

            for name in caches:  # warm up (uploads, sky levels, relight)
                frame(name)
            for _ in range(args.frames):
                for name in caches:
                    times[name].append(frame(name))
            gpu.state.depth_test_set("NONE")
        off.free()
        shader._shaders = {}
        print(
            f"order {order}, {len(objects)} objects at {args.resolution}^2 texels, {size}x{size}, {args.frames} rounds:"
        )
        for name, values in times.items():
            print(
                f"  {name:24s} median {1e3 * statistics.median(values):7.1f} ms (range {1e3 * min(values):.1f}-{1e3 * max(values):.1f})"
            )
        for a, b in (
            ("specular, occlusion", "specular, no occlusion"),
            ("specular, no occlusion", "diffuse"),
            ("specular, occlusion", "diffuse"),
        ):
            ratios = [x / y for x, y in zip(times[a], times[b])]
            print(f"  {a} / {b}: {statistics.median(ratios):.2f} (range {min(ratios):.2f}-{max(ratios):.2f})")
    print(f"load average {os.getloadavg()}")
    prt_addon.unregister()


if __name__ == "__main__":
    main()
