"""Principled maps benchmark: the frame cost of a sphere whose Roughness and Metallic, or IOR, come from an image, against the same sphere with constants.

    .venv/bin/python benchmarks/bench_spec_maps.py [--triangles 200000] [--frames 11] [--size 512] [--order 8]

Four copies of one UV sphere, drawn one at a time in turn, frame by frame in one run (each frame
synchronised by reading a pixel back): constant roughness and metallic; the same with an image on
its Base Color (the textured per-corner draw the maps also use); Roughness and Metallic from a
metallic-roughness image; IOR from an image (docs/specular.md). Ratios are what to read (llvmpipe
on 2 busy cores), with the range of each variant's ratio over the frames' rounds.
"""

import argparse
import math
import os
import statistics
import sys
import time

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, ".."))
sys.path.insert(0, here)
sys.path.insert(0, os.path.join(here, "..", "tests"))

import bpy
import gpu
import mathutils
from bench_display import write_transfer
from helpers import spec_map_scenes as maps
from helpers.albedo_scenes import image_material
from helpers.worlds import image_world, sunny_image

import prt_addon
from prt_addon.blender.display import draw as display_draw, offscreen
from prt_addon.blender.world import projection


def sphere(name, triangles, material):
    segments = int(round(math.sqrt(triangles)))
    bpy.ops.mesh.primitive_uv_sphere_add(segments=segments, ring_count=max(3, triangles // (2 * segments) + 1))
    obj = bpy.context.active_object
    obj.name = name
    obj.data.shade_smooth()
    obj.data.materials.append(material)
    return obj


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--triangles", type=int, default=200_000)
    parser.add_argument("--frames", type=int, default=11)
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--order", type=int, default=8)
    args = parser.parse_args()

    bpy.ops.wm.read_factory_settings(use_empty=True)
    prt_addon.register()
    assert offscreen.ensure_gpu()
    scene = bpy.context.scene
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    cam.location, cam.rotation_euler = (0.0, -4.0, 0.0), (math.pi / 2, 0.0, 0.0)
    scene.camera = cam
    image_world(bpy, scene, sunny_image(256, 512), euler=(0.0, 0.0, 0.3))
    scene.prt_display.specular = True
    orm = maps.orm_image(bpy)
    textured = image_material(bpy, "textured", maps.quadrant_image(bpy, "base", maps.ID_COLOURS, "sRGB"))
    objects = {
        "constant": sphere("constant", args.triangles, maps.principled(bpy, "constant", roughness=0.5)[0]),
        "base colour image": sphere("textured", args.triangles, textured),
        "roughness and metallic image": sphere("mapped", args.triangles, maps.orm_material(bpy, orm)[0]),
        "IOR image": sphere(
            "ior", args.triangles, maps.socket_material(bpy, "ior", maps.halves_image(bpy, "iors", 1.2, 2.0), "IOR")[0]
        ),
    }
    for obj in objects.values():
        write_transfer(obj, args.order)
    projection.project_and_store(scene, args.order, split_lights=False)
    bpy.context.view_layer.update()
    view, proj = offscreen.camera_matrices(scene, args.size, args.size)
    mvp = mathutils.Matrix((proj @ view).tolist())
    print(f"renderer: {gpu.platform.renderer_get()}")
    print(f"{args.triangles:,} triangles, order {args.order}, {args.size}x{args.size}, median of {args.frames} frames")
    off = gpu.types.GPUOffScreen(args.size, args.size, format="RGBA32F")
    times = {name: [] for name in objects}
    with off.bind():
        fb = gpu.state.active_framebuffer_get()
        gpu.state.depth_test_set("LESS_EQUAL")
        gpu.state.depth_mask_set(True)

        def frame(obj):
            fb.clear(color=(0, 0, 0, 0), depth=1.0)
            t0 = time.perf_counter()
            display_draw.draw_objects(scene, mvp, [obj])
            fb.read_color(args.size // 2, args.size // 2, 1, 1, 4, 0, "FLOAT")
            return time.perf_counter() - t0

        for obj in objects.values():
            frame(obj)  # warm up (upload, compile)
        for _ in range(args.frames):
            for name, obj in objects.items():
                times[name].append(frame(obj))
        gpu.state.depth_test_set("NONE")
    off.free()
    base = statistics.median(times["constant"])
    for name, values in times.items():
        ms = statistics.median(values)
        rounds = sorted(v / c for v, c in zip(values, times["constant"]))
        print(
            f"{name:>30}: {ms * 1e3:8.1f} ms  {ms / base:5.2f}x the constant "
            f"(per round {rounds[0]:.2f}-{rounds[-1]:.2f}, median {statistics.median(rounds):.2f})"
        )
    prt_addon.unregister()


if __name__ == "__main__":
    main()
