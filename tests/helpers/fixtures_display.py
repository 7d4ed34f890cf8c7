"""Display fixtures: a lit, baked scene; a ground under suns for the shadow maps."""

import pytest

from helpers.display_scenes import add_camera, add_env_world, set_light
from helpers.shadow_scenes import SIZE, make_box, make_ground, sky_light


@pytest.fixture
def lit_scene(bpy_module, empty_scene, gpu_ready):
    scene = empty_scene
    add_env_world(bpy_module, scene)
    add_camera(bpy_module, scene)
    return scene


@pytest.fixture
def ground_scene(bpy_module, empty_scene, gpu_ready):
    scene = empty_scene
    add_env_world(bpy_module, scene)
    add_camera(bpy_module, scene, location=(0.0, 0.0, 12.0), euler=(0.0, 0.0, 0.0), size=SIZE)
    ground = make_ground(bpy_module, scene)
    make_box(bpy_module, scene)
    set_light(scene, sky_light())
    scene.prt_display.albedo_source = "WHITE"
    bpy_module.context.view_layer.update()
    return scene, ground
