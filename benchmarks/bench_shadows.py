"""Sun-shadow benchmark: frame cost with 0, 1 and 4 lights and a wide light against the PRT-only frame.

    .venv/bin/python benchmarks/bench_shadows.py [--triangles 1000000] [--frames 11] [--size 512]

One baked UV sphere of N triangles over a baked ground quad, drawn by display.draw_objects into a
512x512 RGBA32F offscreen with depth test, each frame synchronised by a one-pixel read-back.
Per light count two variants: "cached" (the shadow maps are reused) and "map drawn" (every
frame turns the lights a little, so every map is drawn again: the cost of rotating the HDRI).
"1 wide light" is a light of 16 samples over a 20 degree cap, drawn from as many maps as the
triangle budget gives (core.lights.shadow_views) at the wide maps' resolution. All variants are
interleaved frame by frame; medians. llvmpipe timings are noisy (shared cores).
"""

import argparse
import math
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bpy
import gpu
import mathutils
import numpy as np
from bench_display import make_sphere, write_transfer

import prt_addon
from prt_addon.blender.display import draw as display_draw, offscreen, shadows
from prt_addon.blender.scene import lighting
from prt_addon.core.lights.extraction import Light
from prt_addon.core.sh import analytic


def make_ground():
    import bmesh

    mesh = bpy.data.meshes.new("Ground")
    bm = bmesh.new()
    bmesh.ops.create_grid(bm, x_segments=1, y_segments=1, size=3.0)
    bm.to_mesh(mesh)
    bm.free()
    obj = bpy.data.objects.new("Ground", mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = (0.0, 0.0, -1.2)
    transfer = np.zeros((len(mesh.vertices), 4), dtype=np.float32)
    transfer[:, 0] = 1.0 / math.sqrt(4.0 * math.pi)
    for k in range(3):
        mesh.color_attributes.new(f"prt_t{k:02d}", "FLOAT_COLOR", "POINT")
    mesh.attributes["prt_t00"].data.foreach_set("color", transfer.ravel())
    mesh["prt_bake"] = {"order": 3, "count": 3, "domain": "POINT"}
    return obj


def suns(count, turn):
    out = []
    for i in range(count):
        a = 2.0 * math.pi * i / max(count, 1) + turn
        d = np.array([0.5 * math.cos(a), 0.5 * math.sin(a), 1.0])
        out.append(Light(direction=d / np.linalg.norm(d), power=(3.0, 2.5, 2.0), angle=0.02))
    return out


def wide_light(turn):
    """One light of 16 samples spread over a 20 degree cap about a tilted direction."""
    z = np.array([0.5 * math.cos(turn), 0.5 * math.sin(turn), 1.0])
    z /= np.linalg.norm(z)
    x = np.cross([1.0, 0.0, 0.0], z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    i = np.arange(16) + 0.5
    tilt = math.radians(20.0) * np.sqrt(i / 16)
    phi = i * math.pi * (3.0 - math.sqrt(5.0))
    dirs = np.cos(tilt)[:, None] * z + np.sin(tilt)[:, None] * (np.cos(phi)[:, None] * x + np.sin(phi)[:, None] * y)
    angle = math.radians(20.0)
    return [Light(z, (3.0, 2.5, 2.0), angle, samples=dirs, weights=np.full(16, 1 / 16), shadow_angle=angle)]


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--triangles", type=int, default=1_000_000)
    parser.add_argument("--frames", type=int, default=11)
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--resolution", type=int, default=shadows.RESOLUTION)
    parser.add_argument("--wide-resolution", type=int, default=shadows.WIDE_RESOLUTION)
    args = parser.parse_args()
    shadows.RESOLUTION = args.resolution
    shadows.WIDE_RESOLUTION = args.wide_resolution

    bpy.ops.wm.read_factory_settings(use_empty=True)
    prt_addon.register()
    assert offscreen.ensure_gpu()
    scene = bpy.context.scene
    scene.prt_display.albedo_source = "WHITE"
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    cam.location = (0.0, -5.0, 2.0)
    cam.rotation_euler = (math.radians(70.0), 0.0, 0.0)
    scene.camera = cam
    obj = make_sphere(args.triangles)
    write_transfer(obj, 3)
    ground = make_ground()
    lighting.set_light_override(scene, analytic.cap_coeffs(3, (1, 0, 0), 0.3, radiance=(5, 4, 3)))
    bpy.context.view_layer.update()
    view, proj = offscreen.camera_matrices(scene, args.size, args.size)
    vp = mathutils.Matrix((proj @ view).tolist())
    objects = [obj, ground]
    obj.data.calc_loop_triangles()
    print(f"renderer: {gpu.platform.renderer_get()}")
    print(
        f"mesh: {len(obj.data.loop_triangles):,} triangles (+ a 2-triangle ground); {args.size}x{args.size}; "
        f"shadow maps {shadows.RESOLUTION}x{shadows.RESOLUTION}, wide {shadows.WIDE_RESOLUTION}; median of {args.frames} interleaved frames"
    )

    variants = [
        ("PRT only", 0, False),
        ("1 light, cached", 1, False),
        ("1 light, map drawn", 1, True),
        ("4 lights, cached", 4, False),
        ("4 lights, maps drawn", 4, True),
        ("1 wide light, cached", -1, False),
        ("1 wide light, drawn", -1, True),
    ]
    times = {name: [] for name, _, _ in variants}
    states = {name: {} for name, _, _ in variants}  # each variant keeps its own maps
    off = gpu.types.GPUOffScreen(args.size, args.size, format="RGBA32F")
    with off.bind():
        fb = gpu.state.active_framebuffer_get()
        gpu.state.depth_test_set("LESS_EQUAL")
        gpu.state.depth_mask_set(True)
        for frame in range(args.frames + 1):
            for name, count, turning in variants:
                turn = 1e-3 * (frame + 1) if turning else 0.0
                lighting.set_lights_override(scene, wide_light(turn) if count < 0 else suns(count, turn))
                shadows._states.clear()
                shadows._states.update(states[name])
                fb.clear(color=(0, 0, 0, 0), depth=1.0)
                t0 = time.perf_counter()
                display_draw.draw_objects(scene, vp, objects)
                fb.read_color(args.size // 2, args.size // 2, 1, 1, 4, 0, "FLOAT")
                if frame:  # frame 0 warms up (uploads, compiles, first maps)
                    times[name].append(time.perf_counter() - t0)
                states[name] = dict(shadows._states)
        gpu.state.depth_test_set("NONE")
    off.free()
    base = statistics.median(times["PRT only"])
    print(f"{'variant':<22} {'ms':>8} {'/ PRT only':>10}")
    for name, _, _ in variants:
        t = statistics.median(times[name])
        print(f"{name:<22} {t * 1e3:>8.1f} {t / base:>10.2f}")
    t0 = time.perf_counter()
    shadows.caster_triangles(shadows.caster_objects(scene), None)
    print(f"caster read (on a geometry change only): {(time.perf_counter() - t0) * 1e3:.1f} ms")
    prt_addon.unregister()


if __name__ == "__main__":
    main()
