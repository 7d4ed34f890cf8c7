"""Benchmark of the world projection; figures are pasted in docs/world.md.

Run: .venv/bin/python benchmarks/bench_world.py [repeats]
Times (median of `repeats`, default 5) of prt.project_world on each bundled HDRI at orders 3, 8
and 16 (read + reduce + project + rotate + store, through the operator), of a rotation update
(current_world_coeffs after the Mapping rotation changed, i.e. a cache miss), and of the
render fallback (a Sky Texture rendered by Cycles) once per order.
"""

import math
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import bpy

import prt_addon
from prt_addon.blender.world import projection as world_projection

ORDERS = (3, 8, 16)
HDRIS = ("city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset")


def median_time(fn, repeats):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main():
    repeats = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    prt_addon.register()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    world = bpy.data.worlds.new("World")
    scene.world = world
    tree = world.node_tree
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    coords = tree.nodes.new("ShaderNodeTexCoord")
    mapping = tree.nodes.new("ShaderNodeMapping")
    tree.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    tree.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    tree.links.new(env.outputs["Color"], tree.nodes["Background"].inputs["Color"])
    folder = bpy.utils.system_resource("DATAFILES", path="studiolights/world")

    print(f"bpy {bpy.app.version_string}, median of {repeats} runs, times in ms")
    print("prt.project_world (1024x512 EXR, image already loaded):")
    print(f"{'HDRI':<10}" + "".join(f"{'order ' + str(n):>10}" for n in ORDERS) + f"{'trunc@8':>10}")
    for name in HDRIS:
        env.image = bpy.data.images.load(os.path.join(folder, f"{name}.exr"))
        row, truncation = [], 0.0
        for order in ORDERS:
            bpy.ops.prt.project_world(order=order)  # warm-up (loads the image once)
            row.append(1e3 * median_time(lambda: bpy.ops.prt.project_world(order=order), repeats))
            if order == 8:
                truncation = scene.prt_world.truncation
        print(f"{name:<10}" + "".join(f"{t:>10.1f}" for t in row) + f"{100 * truncation:>9.1f}%")

    print("rotation update (current_world_coeffs after a Mapping change, no projection):")
    for order in ORDERS:
        bpy.ops.prt.project_world(order=order)
        angle = [0.0]

        def update():
            angle[0] += 0.01
            mapping.inputs["Rotation"].default_value = (0.3, 0.2, angle[0])
            world_projection.current_world_coeffs(scene)

        cached = median_time(lambda: world_projection.current_world_coeffs(scene), repeats * 20)
        print(
            f"  order {order:>2}: {1e3 * median_time(update, repeats * 20):.3f} ms "
            f"(unchanged rotation, cached: {1e3 * cached:.3f} ms)"
        )

    print("render fallback (Sky Texture, Cycles panorama 512x256, 16 samples, 2 cores):")
    sky = tree.nodes.new("ShaderNodeTexSky")
    sky.sun_elevation = math.radians(20.0)
    tree.links.new(sky.outputs["Color"], tree.nodes["Background"].inputs["Color"])
    for order in ORDERS:
        t = median_time(lambda: bpy.ops.prt.project_world(order=order), max(1, repeats // 2))
        print(f"  order {order:>2}: {1e3 * t:.0f} ms")
    prt_addon.unregister()


if __name__ == "__main__":
    main()
