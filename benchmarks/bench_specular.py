"""Specular benchmark: the frame cost of a Principled object drawn with its specular against the same
object drawn diffuse only, side by side, at 1M triangles, with and without a split light; the
memory and build time of the prefiltered sky, and the BRDF table's build time.

    .venv/bin/python benchmarks/bench_specular.py [--triangles 1000000] [--frames 11] [--size 512]

The draws alternate frame by frame in one run (each frame synchronised by reading a pixel back):
diffuse and specular, then diffuse and specular with the view moving (each frame from another eye,
which draws the full transfer's occlusion again; its ratio is to the diffuse frames of its own
loop); ratios are what to read, absolute times are for this machine
(llvmpipe on 2 cores).
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
from bench_display import make_sphere, write_transfer
from helpers.worlds import image_world, sunny_image

import prt_addon
from prt_addon.blender.display import draw as display_draw, gpu_cache, offscreen, sky_texture
from prt_addon.blender.world import projection
from prt_addon.core.specular import brdf


def time_frames(scene, obj, mvps, frames, size):
    """Medians of (diffuse, specular, diffuse, specular with the view moving) frames: the first
    two interleaved from the first view of `mvps`, then the last two, the moving one drawn
    alternately from the two views, so that every frame sees another eye (the full transfer's
    occlusion is drawn again, spec_occlusion; in a loop of its own, as the static frames would
    otherwise draw it again after each moved one)."""
    off = gpu.types.GPUOffScreen(size, size, format="RGBA32F")
    times = {"diffuse": [], "specular": [], "diffuse again": [], "moving": []}
    with off.bind():
        fb = gpu.state.active_framebuffer_get()
        gpu.state.depth_test_set("LESS_EQUAL")
        gpu.state.depth_mask_set(True)

        def frame(specular, mvp):
            scene.prt_display.specular = specular
            fb.clear(color=(0, 0, 0, 0), depth=1.0)
            t0 = time.perf_counter()
            display_draw.draw_objects(scene, mvp, [obj])
            fb.read_color(size // 2, size // 2, 1, 1, 4, 0, "FLOAT")  # wait for the GPU
            return time.perf_counter() - t0

        frame(False, mvps[0]), frame(True, mvps[0])  # warm up (upload, compile, sky levels)
        for _ in range(frames):
            times["diffuse"].append(frame(False, mvps[0]))
            times["specular"].append(frame(True, mvps[0]))
        for i in range(frames):
            times["diffuse again"].append(frame(False, mvps[0]))
            times["moving"].append(frame(True, mvps[1 - i % 2]))
        gpu.state.depth_test_set("NONE")
    off.free()
    return [statistics.median(times[k]) for k in times]


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--triangles", type=int, default=1_000_000)
    parser.add_argument("--frames", type=int, default=11)
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--orders", type=int, nargs="+", default=[4, 8])
    args = parser.parse_args()

    bpy.ops.wm.read_factory_settings(use_empty=True)
    prt_addon.register()
    assert offscreen.ensure_gpu()  # before building the large mesh
    scene = bpy.context.scene
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    cam.location = (0.0, -4.0, 0.0)
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)
    scene.camera = cam
    image_world(bpy, scene, sunny_image(256, 512), euler=(0.0, 0.0, 0.3))
    obj = make_sphere(args.triangles)
    mat = bpy.data.materials.new("Principled")
    if mat.node_tree is None:
        mat.use_nodes = True
    obj.data.materials.append(mat)
    bpy.context.view_layer.update()
    view, proj = offscreen.camera_matrices(scene, args.size, args.size)
    mvp = mathutils.Matrix((proj @ view).tolist())
    orbit = mathutils.Matrix.Rotation(0.01, 4, "Z")  # the camera turned by 0.01 rad about the sphere
    mvps = (mvp, mathutils.Matrix((proj @ view @ orbit).tolist()))
    obj.data.calc_loop_triangles()
    print(f"renderer: {gpu.platform.renderer_get()}")
    print(
        f"mesh: {len(obj.data.loop_triangles):,} triangles, {len(obj.data.vertices):,} vertices; "
        f"{args.size}x{args.size} offscreen, median of {args.frames} interleaved frames"
    )
    start = time.perf_counter()
    brdf.brdf_table()
    print(
        f"BRDF table {brdf.TABLE_SIZE}x{brdf.TABLE_SIZE} ({brdf.SAMPLES} samples each): {time.perf_counter() - start:.2f} s"
    )
    print(
        f"{'order':>5} {'split lights':>12} {'diffuse ms':>10} {'specular ms':>11} {'ratio':>6} "
        f"{'view moving ms':>14} {'ratio':>6}"
    )
    for order in args.orders:
        write_transfer(obj, order)
        for split in (False, True):
            projection.project_and_store(scene, order, split_lights=split)
            gpu_cache.clear_caches()
            diffuse, specular, diffuse_again, moving = time_frames(scene, obj, mvps, args.frames, args.size)
            lights = len(projection.current_world_lights(scene))
            print(
                f"{order:>5} {lights:>12} {diffuse * 1e3:>10.1f} {specular * 1e3:>11.1f} {specular / diffuse:>6.2f} "
                f"{moving * 1e3:>14.1f} {moving / diffuse_again:>6.2f}"
            )
    sky = sky_texture.sky_texture(scene)
    print(
        f"prefiltered sky: {sky.levels} levels of {sky.width}x{sky.height} RGBA16F = {sky.nbytes / 2**20:.2f} MiB, "
        f"built in {sky.seconds:.2f} s (once per projection; a rotation costs nothing)"
    )
    prt_addon.unregister()


if __name__ == "__main__":
    main()
