"""The baked scene the glTF export's tests share (a pytest plugin of tests/conftest.py)."""

import numpy as np
import pytest

from helpers.gltf import _world


@pytest.fixture
def baked(empty_scene, bpy_module):
    """Ico sphere (smooth, POINT) on a grid (POINT), a flat cube (CORNER); lighting with a light."""
    from prt_addon import api
    from prt_addon.blender.scene import lighting
    from prt_addon.core.lights.extraction import Light

    bpy = bpy_module
    _world(bpy)
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=2, location=(0.0, 0.0, 1.0), rotation=(0.3, 0.5, 0.7))
    sphere = bpy.context.object
    sphere.data.shade_smooth()
    bpy.ops.mesh.primitive_grid_add(size=4.0, x_subdivisions=6, y_subdivisions=6)
    grid = bpy.context.object
    bpy.ops.mesh.primitive_cube_add(size=0.6, location=(1.2, 0.8, 0.3), rotation=(0.0, 0.2, 1.0))
    cube = bpy.context.object
    cube.data.shade_flat()
    api.project_world(order=4)
    api.bake([sphere, grid], order=3, samples=64)
    api.bake([cube], order=4, samples=64)
    lighting.set_lights_override(empty_scene, [Light(np.array([0.0, 0.6, 0.8]), np.array([3.0, 2.0, 1.0]), 0.05)])
    yield empty_scene, {"sphere": sphere, "grid": grid, "cube": cube}
    lighting.clear_light_overrides()
