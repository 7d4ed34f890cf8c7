"""Bake a scene with PRT Lighting from a script, headless.

With Blender and the extension installed:

    blender -b -P examples/bake_scene.py -- [--hdri forest] [--order 4] [--samples 256] [--png out.png]

With Blender as a Python module (the `bpy` package), from the repository root:

    .venv/bin/python examples/bake_scene.py [--png out.png]

It builds Suzanne on a ground plane under one of Blender's bundled HDRIs, projects the world,
bakes shadowed transfer, prints the bake report, shades the mesh at two lighting rotations and,
with --png, renders the camera view with the PRT shader.
"""

import argparse
import atexit
import math
import os
import sys

import bpy
import numpy as np


def load_prt():
    """The add-on's Python API: the installed extension if there is one, else this repository."""
    for name in list(sys.modules):
        if name.startswith("bl_ext.") and name.endswith(".prt_lighting"):
            return __import__(name + ".prt_addon.api", fromlist=["api"])
    import addon_utils

    for module in addon_utils.modules():
        if module.__name__.endswith(".prt_lighting"):
            addon_utils.enable(module.__name__, default_set=True)
            return __import__(module.__name__ + ".prt_addon.api", fromlist=["api"])
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    import prt_addon

    prt_addon.register()
    # bpy 4.x as a module frees classes still registered at exit after Python has shut down and
    # segfaults; unregister while Python still runs (full Blender disables add-ons itself).
    atexit.register(prt_addon.unregister)
    from prt_addon import api

    return api


def build_scene(hdri):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=80, y_subdivisions=80, size=8)  # per-vertex shadows
    ground = bpy.context.object
    bpy.ops.mesh.primitive_monkey_add(location=(0, 0, 1), rotation=(0, 0, math.radians(-20)))
    monkey = bpy.context.object
    bpy.ops.object.modifier_add(type="SUBSURF")  # the bake needs the topology it stores on:
    bpy.ops.object.modifier_apply(modifier=monkey.modifiers[0].name)  # apply it first
    monkey.data.shade_smooth()
    world = bpy.data.worlds.new("HDRI")
    if world.node_tree is None:  # Blender 4.x
        world.use_nodes = True
    scene.world = world
    env = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
    folder = bpy.utils.system_resource("DATAFILES", path="studiolights/world")
    env.image = bpy.data.images.load(os.path.join(folder, f"{hdri}.exr"), check_existing=True)
    world.node_tree.links.new(env.outputs["Color"], world.node_tree.nodes["Background"].inputs["Color"])
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera)
    camera.location = (4.6, -5.4, 3.4)
    camera.rotation_euler = (math.radians(68), 0.0, math.radians(41))
    scene.camera = camera
    scene.render.resolution_x, scene.render.resolution_y = 480, 320
    return scene, ground, monkey


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hdri", default="forest", help="a bundled studio-light HDRI")
    parser.add_argument("--order", type=int, default=4)
    parser.add_argument("--samples", type=int, default=256)
    parser.add_argument("--png", help="render the PRT view to this PNG file")
    args = parser.parse_args(argv)

    api = load_prt()
    scene, ground, monkey = build_scene(args.hdri)

    light = api.project_world(scene, order=args.order)  # stored on the scene, (order^2, 3)
    print(f"world projected: {light.shape[0]} coefficients, c0 = {np.round(light[0], 3)}")

    report = api.bake([monkey, ground], order=args.order, samples=args.samples)
    for line in report.summary_lines():
        print(line)

    # Rotate the lighting: the world's Mapping node (created if needed) drives Cycles, EEVEE and
    # the PRT display alike; prt.set_light_rotation is the sidebar's operator.
    for angle in (0, 90):
        bpy.ops.prt.set_light_rotation(rotation=(0.0, 0.0, math.radians(angle)))
        radiance = api.shade(monkey)  # (vertices, 3): what the display shader draws, albedo excluded
        print(f"lighting turned {angle:3d} deg: mean radiance {np.round(radiance.mean(axis=0), 4)}")

    if args.png:
        bpy.ops.prt.set_light_rotation(rotation=(0.0, 0.0, 0.0))
        image = api.render_view(scene)  # (H, W, 4) linear, offscreen, PRT shader
        api.save_png(image, os.path.abspath(args.png), scene, background=(0.05, 0.05, 0.05))
        print(f"wrote {args.png}")
    return report


if __name__ == "__main__":
    argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else sys.argv[1:]
    main(argv)
