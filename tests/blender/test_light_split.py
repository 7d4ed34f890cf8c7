"""The light split on the Blender side: projection, storage, rotation, bad input, and Cycles."""

import math

import numpy as np
import pytest
from helpers.worlds import (
    Y0,
    image_world,
    new_world,
    sunny_image,
)

from prt_addon.core.lights import extraction as core_lights
from prt_addon.core.sh import rotation


def stored_lights(scene):
    from prt_addon.blender.world import light_split

    return light_split.stored(scene)


@pytest.mark.parametrize("size", [(128, 64), (1024, 512)])  # the second is reduced to 512x256
def test_energy_sky_plus_lights_is_the_unsplit_projection(bpy_module, empty_scene, size):
    from prt_addon import api

    width, height = size
    image_world(bpy_module, empty_scene, sunny_image(height, width), strength=1.7)
    unsplit = api.project_world(empty_scene, 8, split_lights=False)
    assert not api.world_lights(empty_scene)
    sky = api.project_world(empty_scene, 8, split_lights=True)
    lights = api.world_lights(empty_scene)
    assert 1 <= len(lights) <= 4
    total = sky[0] + sum(light["power"] for light in lights) * Y0
    np.testing.assert_allclose(total, unsplit[0], rtol=1e-9)
    settings = empty_scene.prt_world
    assert settings.split_lights  # the override did not change the setting
    assert settings.light_count == len(lights)
    assert 0.0 < settings.light_share < 1.0
    assert empty_scene.prt_world.projected_size[1] == min(height, 256)


def test_mapping_turns_lights_and_sky_together(bpy_module, empty_scene):
    from prt_addon import api
    from prt_addon.blender.world import projection as world_projection

    euler = (0.3, -0.2, 0.7)
    _, mapping = image_world(bpy_module, empty_scene, sunny_image(64, 128), euler=euler)
    coeffs = api.project_world(empty_scene, 6)
    q = world_projection.current_rotation(empty_scene)
    image_lights = stored_lights(empty_scene)
    assert image_lights
    by_hand = core_lights.rotate_lights(image_lights, q)
    got = api.world_lights(empty_scene)
    for light, expected in zip(got, by_hand):
        np.testing.assert_allclose(light["direction"], expected.direction, atol=1e-12)
        np.testing.assert_allclose(light["power"], expected.power, rtol=1e-12)
    np.testing.assert_allclose(coeffs, rotation.rotate(world_projection.stored_image_coeffs(empty_scene), q))
    # Turn the node: lights and SH follow live, and agree with a fresh projection.
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(40.0))
    live_sh, live = api.world_lighting(empty_scene), api.world_lights(empty_scene)
    assert not np.allclose(live[0]["direction"], got[0]["direction"])
    fresh_sh = api.project_world(empty_scene, 6)
    fresh = api.world_lights(empty_scene)
    np.testing.assert_allclose(live_sh, fresh_sh, atol=1e-12)
    for a, b in zip(live, fresh):
        np.testing.assert_allclose(a["direction"], b["direction"], atol=1e-12)
        np.testing.assert_allclose(a["power"], b["power"], rtol=1e-12)
    # A light at image direction s is where Cycles shows that texel: at Q s in the world.
    q = world_projection.current_rotation(empty_scene)
    np.testing.assert_allclose(q @ stored_lights(empty_scene)[0].direction, fresh[0]["direction"], atol=1e-12)


def bake_plane_and_box(bpy, scene, order=4):
    from prt_addon import api

    bpy.ops.mesh.primitive_grid_add(x_subdivisions=8, y_subdivisions=8, size=4.0)
    ground = bpy.context.active_object
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 1.0))
    box = bpy.context.active_object
    api.bake([ground, box], order=order, samples=64)
    return ground, box


def test_projection_without_lights_key_still_loads_and_shades(bpy_module, empty_scene, tmp_path):
    from prt_addon import api
    from prt_addon.blender.world import light_split

    image_world(bpy_module, empty_scene, sunny_image(64, 128))
    ground, _box = bake_plane_and_box(bpy_module, empty_scene)
    api.project_world(empty_scene, 4)
    with_lights = api.shade(ground, empty_scene)
    assert api.world_lights(empty_scene)
    del empty_scene[light_split.LIGHTS_KEY]  # as a projection stored before the split
    path = str(tmp_path / "old.blend")
    bpy_module.ops.wm.save_as_mainfile(filepath=path)
    bpy_module.ops.wm.open_mainfile(filepath=path)
    scene = bpy_module.context.scene
    assert api.world_lights(scene) == []
    ground = scene.objects["Grid"]
    without = api.shade(ground, scene)
    assert without.shape == with_lights.shape
    assert np.all(np.isfinite(without))
    assert without.mean() < with_lights.mean()


def test_samples_survive_saving_and_lights_stored_without_them_are_discs(bpy_module, empty_scene, tmp_path):
    """The samples are stored next to the lights and come back after a save; a file whose
    projection predates them (no samples key) loads the same lights as discs."""
    from prt_addon import api
    from prt_addon.blender.world import light_split

    image_world(bpy_module, empty_scene, sunny_image(64, 128))
    api.project_world(empty_scene, 4)
    before = api.world_lights(empty_scene)
    assert before
    assert before[0]["samples"] is not None
    np.testing.assert_allclose(before[0]["weights"].sum(), 1.0, rtol=1e-12)
    path = str(tmp_path / "samples.blend")
    bpy_module.ops.wm.save_as_mainfile(filepath=path)
    bpy_module.ops.wm.open_mainfile(filepath=path)
    after = api.world_lights(bpy_module.context.scene)
    for a, b in zip(before, after, strict=True):
        np.testing.assert_allclose(a["samples"], b["samples"], atol=1e-12)
        np.testing.assert_allclose(a["weights"], b["weights"], rtol=1e-12)
    scene = bpy_module.context.scene
    del scene[light_split.SAMPLES_KEY]  # as a projection stored before the samples
    old = api.world_lights(scene)
    assert len(old) == len(before)
    assert all(light["samples"] is None for light in old)
    np.testing.assert_allclose(old[0]["direction"], before[0]["direction"], atol=1e-12)
    scene[light_split.SAMPLES_KEY] = [3.0, 1.0]  # unreadable samples: the lights still load, as discs
    assert [light["samples"] for light in api.world_lights(scene)] == [None] * len(before)


def test_light_is_shadowed_by_the_scene(bpy_module, empty_scene):
    """Under a light straight above, the ground below the box is dark and the rest lit."""
    from prt_addon import api
    from prt_addon.blender.scene import lighting

    new_world(bpy_module, empty_scene, color=(0.0, 0.0, 0.0), strength=0.0)
    image_world(bpy_module, empty_scene, np.full((8, 16, 3), 1e-3))
    ground, box = bake_plane_and_box(bpy_module, empty_scene)
    api.project_world(empty_scene, 2)
    light = core_lights.Light([0.0, 0.0, 1.0], [3.0, 3.0, 3.0], math.radians(1.0))
    lighting.set_lights_override(empty_scene, [light])
    try:
        values = api.shade(ground, empty_scene)[:, 0]
        on_box = api.shade(box, empty_scene)[:, 0]  # a CORNER bake: one row per face corner
    finally:
        lighting.set_lights_override(empty_scene, None)
    xy = np.array([ground.matrix_world @ v.co for v in ground.data.vertices])[:, :2]
    under = np.all(np.abs(xy) < 0.45, axis=1)
    outside = np.any(np.abs(xy) > 0.55, axis=1)
    assert under.any()
    assert outside.any()
    assert values[under].max() < 0.01
    np.testing.assert_allclose(values[outside], 3.0 / math.pi, rtol=0.02)
    assert len(on_box) == len(box.data.loops)
    normals = np.empty(len(box.data.loops) * 3, np.float32)
    box.data.corner_normals.foreach_get("vector", normals)
    top = normals.reshape(-1, 3)[:, 2] > 0.99
    np.testing.assert_allclose(on_box[top], 3.0 / math.pi, rtol=0.02)
    assert on_box[~top].max() < 0.01


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(threshold=-1.0),
        dict(threshold=float("nan")),
        dict(threshold="big"),
        dict(max_lights=9),
        dict(max_lights=-1),
        dict(max_lights=2.0),
    ],
)
def test_bad_split_settings_change_nothing(bpy_module, empty_scene, kwargs):
    from prt_addon import api
    from prt_addon.blender.world.nodes import WorldError as Error

    image_world(bpy_module, empty_scene, sunny_image(64, 128))
    before = api.project_world(empty_scene, 4)
    token, lights = empty_scene.prt_world.token, api.world_lights(empty_scene)
    with pytest.raises(Error, match="threshold|lights"):
        api.project_world(empty_scene, 6, **kwargs)
    assert empty_scene.prt_world.token == token
    assert empty_scene.prt_world.stored_order == 4
    np.testing.assert_array_equal(api.world_lighting(empty_scene), before)
    assert len(api.world_lights(empty_scene)) == len(lights)


def test_one_colour_image_and_high_threshold_give_no_lights(bpy_module, empty_scene):
    from prt_addon import api
    from prt_addon.blender.world import light_split

    image_world(bpy_module, empty_scene, np.full((32, 64, 3), 0.7))
    api.project_world(empty_scene, 4)
    settings = empty_scene.prt_world
    assert api.world_lights(empty_scene) == []
    assert settings.light_count == 0
    assert settings.stored_split
    assert light_split.summary(settings) == ["No compact bright source:", "no lights"]
    image_world(bpy_module, empty_scene, sunny_image(64, 128))
    api.project_world(empty_scene, 4, threshold=1e6)
    assert api.world_lights(empty_scene) == []
    settings.auto_threshold, settings.light_threshold = False, 1e6  # the panel's manual threshold
    api.project_world(empty_scene, 4)
    assert api.world_lights(empty_scene) == []
    settings.auto_threshold = True  # Auto ignores the number
    api.project_world(empty_scene, 4)
    lines = light_split.summary(settings)
    assert lines[0].startswith(f"{settings.light_count} light")
    assert all(len(x) <= 32 for x in lines)
    new_world(bpy_module, empty_scene, color=(0.2, 0.3, 0.4))
    api.project_world(empty_scene, 4)
    assert api.world_lights(empty_scene) == []
    assert not settings.stored_split


# --- against Cycles ---------------------------------------------------------------------------
