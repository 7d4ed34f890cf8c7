"""The light split against Cycles: Suzanne on a ground under city.exr, and a world that only Cycles renders split too."""

import math
import os
import time

import numpy as np
from helpers.cycles import cycles_vertex_bake
from helpers.worlds import (
    Y0,
    add_mapping,
    new_world,
    use_image,
)

from prt_addon.core.lights import extraction as core_lights

CYCLES_SAMPLES = 512


def rel_rmse_luminance(values, reference):
    a, b = values @ core_lights.LUMA, reference @ core_lights.LUMA
    return float(np.sqrt(np.mean((a - b) ** 2)) / np.sqrt(np.mean(b**2)))


def test_suzanne_on_ground_under_city_against_cycles(bpy_module, empty_scene):
    from prt_addon import api

    bpy = bpy_module
    scene = empty_scene
    path = os.path.join(bpy.utils.system_resource("DATAFILES", path="studiolights/world"), "city.exr")
    world = new_world(bpy, scene)
    env = use_image(world, bpy.data.images.load(path))
    add_mapping(world, env, (0.0, 0.0, math.radians(40.0)))
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=24, y_subdivisions=24, size=6.0)
    ground = bpy.context.active_object
    bpy.ops.mesh.primitive_monkey_add(location=(0.0, 0.0, 0.75), rotation=(0.0, 0.0, math.radians(30.0)))
    suzanne = bpy.context.active_object
    modifier = suzanne.modifiers.new("sub", "SUBSURF")
    modifier.levels = 1
    bpy.ops.object.modifier_apply(modifier=modifier.name)
    suzanne.data.shade_smooth()
    objects = [suzanne, ground]
    material = bpy.data.materials.new("white")
    for obj in objects:
        obj.data.materials.append(material)

    start = time.perf_counter()
    api.bake(objects, order=8, samples=1024)
    prt_seconds = time.perf_counter() - start
    start = time.perf_counter()
    reference = np.concatenate(list(cycles_vertex_bake(bpy, scene, objects, CYCLES_SAMPLES).values()))
    cycles_seconds = time.perf_counter() - start

    api.project_world(scene, 8, split_lights=False)
    unsplit = np.concatenate([api.shade(obj, scene) for obj in objects])
    api.project_world(scene, 8, split_lights=True)
    assert api.world_lights(scene)
    start = time.perf_counter()
    split = np.concatenate([api.shade(obj, scene) for obj in objects])
    shade_seconds = time.perf_counter() - start
    error_split = rel_rmse_luminance(split, reference)
    error_unsplit = rel_rmse_luminance(unsplit, reference)
    print(
        f"\nvertices {len(reference)}, split {100 * error_split:.2f} %, unsplit {100 * error_unsplit:.2f} %, "
        f"PRT bake {prt_seconds:.1f} s, Cycles {cycles_seconds:.1f} s, shade {shade_seconds:.2f} s"
    )
    assert error_split < 0.025
    assert error_unsplit > 0.04


def test_rendered_world_is_split_too(bpy_module, empty_scene):
    """A Sky Texture goes through the Cycles render fallback; its sun becomes a light."""
    from prt_addon import api

    world = new_world(bpy_module, empty_scene)
    tree = world.node_tree
    sky = tree.nodes.new("ShaderNodeTexSky")
    tree.links.new(sky.outputs["Color"], tree.nodes["Background"].inputs["Color"])
    unsplit = api.project_world(empty_scene, 4, split_lights=False)
    split = api.project_world(empty_scene, 4, split_lights=True)
    assert empty_scene.prt_world.source_kind == "RENDER"
    lights = api.world_lights(empty_scene)
    assert lights
    assert empty_scene.prt_world.strongest_elevation > 0.0
    total = split[0] + sum(light["power"] for light in lights) * Y0
    np.testing.assert_allclose(total, unsplit[0], rtol=1e-3)  # two renders: their noise differs
