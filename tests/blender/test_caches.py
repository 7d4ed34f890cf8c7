"""One owner for the Blender layer's caches: a scene's lighting override survives renaming it, and
file load and unregister() empty every cache (the lights' occluders included)."""

import numpy as np
from helpers.caches import _ground_and_box


def test_a_light_override_survives_renaming_the_scene(bpy_module, empty_scene):
    from prt_addon.blender.scene import lighting

    light = np.zeros((4, 3))
    light[0] = 1.0
    lighting.set_light_override(empty_scene, light)
    empty_scene.name = "Renamed by the user"
    got = lighting.world_light(empty_scene)
    assert got is not None
    np.testing.assert_array_equal(got, light)
    lighting.set_light_override(empty_scene, None)
    assert lighting.world_light(empty_scene) is None


def test_the_lights_occluders_are_dropped_on_file_load_and_unregister(bpy_module, empty_scene):
    import prt_addon
    from prt_addon.blender.scene import light_shading

    bpy = bpy_module
    _ground_and_box(bpy)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    assert light_shading.scene_occluder(depsgraph) is not None
    assert light_shading._occluders
    bpy.ops.wm.read_homefile(use_empty=True)  # load_pre runs the clears
    assert not light_shading._occluders
    _ground_and_box(bpy)
    assert light_shading.scene_occluder(bpy.context.evaluated_depsgraph_get()) is not None
    prt_addon.unregister()
    try:
        assert not light_shading._occluders
    finally:
        prt_addon.register()
