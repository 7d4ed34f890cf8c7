"""Live PRT display under rotation: the lighting, a world Mapping node, the object, and the projected world.

Needs the GPU initialised headless; helpers come from tests/helpers/display_scenes.py, the lit_scene fixture from tests/helpers/fixtures_display.py.
"""

import math
import warnings

import numpy as np
import pytest
from helpers.display_scenes import bake_sphere, local_positions, sample_at_vertices, set_light, sun_sky_light


def _bright_side(values, normals, axis):
    """Mean luminance on the +axis side minus that on the -axis side."""
    lum = values @ np.array([0.2126, 0.7152, 0.0722])
    d = normals @ np.asarray(axis, dtype=np.float64)
    return lum[d > 0.5].mean() - lum[d < -0.5].mean()


def test_lighting_rotation_180_moves_bright_side(bpy_module, lit_scene):
    import prt_addon.api as api
    from prt_addon.blender.world import nodes as world_nodes

    order = 4
    obj = bake_sphere(bpy_module, order)
    set_light(lit_scene, sun_sky_light(order))
    lit_scene.prt_display.albedo_source = "WHITE"
    normals = local_positions(obj.data)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    before = api.shade(obj, lit_scene)
    image_before = api.render_view(lit_scene, 256, 256)
    assert _bright_side(before, normals, (1, 0, 0)) > 0.5  # the sun is along +X

    assert bpy_module.ops.prt.set_light_rotation(rotation=(0.0, 0.0, math.pi)) == {"FINISHED"}
    mapping = world_nodes.find_mapping_node(lit_scene.world)
    assert mapping is not None  # the sidebar operator created the world's Mapping node
    assert tuple(mapping.inputs["Rotation"].default_value) == pytest.approx((0.0, 0.0, math.pi))
    after = api.shade(obj, lit_scene)
    image_after = api.render_view(lit_scene, 256, 256)
    assert _bright_side(after, normals, (1, 0, 0)) < -0.5
    # The sphere is symmetric: the 180-degree rotation mirrors the shading x -> -x, y -> -y.
    mirror = np.argmin(
        np.linalg.norm(normals[:, None, :2] + normals[None, :, :2], axis=2)
        + np.abs(normals[:, None, 2] - normals[None, :, 2]),
        axis=1,
    )
    np.testing.assert_allclose(after, before[mirror], rtol=1e-4, atol=1e-4)

    # In the camera view (+X to the right) the bright half moves from right to left.
    def halves(img):
        lum = img[..., :3] @ np.array([0.2126, 0.7152, 0.0722])
        return lum[:, :128].sum(), lum[:, 128:].sum()

    left, right = halves(image_before)
    assert right > 2.0 * left
    left, right = halves(image_after)
    assert left > 2.0 * right


def test_editing_mapping_node_directly_updates_display(bpy_module, lit_scene):
    """POINT Mapping +90 deg about Z: the world is image(R d), so the +X sun appears at -Y
    (docs/world.md, measured against Cycles)."""
    import prt_addon.api as api
    from prt_addon.blender.world import nodes as world_nodes

    order = 4
    obj = bake_sphere(bpy_module, order)
    set_light(lit_scene, sun_sky_light(order))
    lit_scene.prt_display.albedo_source = "WHITE"
    node = world_nodes.ensure_mapping_node(lit_scene.world)
    node.inputs["Rotation"].default_value = (0.0, 0.0, math.pi / 2)
    assert world_nodes.mapping_rotation_euler(lit_scene.world) == pytest.approx((0.0, 0.0, math.pi / 2))
    normals = local_positions(obj.data)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    values = api.shade(obj, lit_scene)
    brightest = normals[np.argmax(values[:, 0])]
    assert brightest @ np.array([0.0, -1.0, 0.0]) > 0.95
    # The drawn image turned with the node as api.shade did (a stale rotation would put the
    # bright side elsewhere and fail this comparison at the vertices).
    image = api.render_view(lit_scene, 128, 128)
    got, visible = sample_at_vertices(bpy_module, obj, lit_scene, image)
    want = values[visible]
    err = np.abs(got - want) / (np.abs(want) + 0.05)
    assert np.median(err) < 0.01, np.median(err)


def test_projected_world_turns_through_a_mapping_node_added_by_hand(bpy_module, lit_scene):
    """The real path, no injected light: an image world projected without a Mapping node, then a
    Mapping node added and turned by hand. The display, api.shade and api.world_lighting all
    follow it, and the +X sun of the image lights the sphere from -Y (POINT, +90 deg about Z)."""
    from helpers.worlds import add_mapping, float_image, image_of, use_image

    import prt_addon.api as api

    order = 4
    world = lit_scene.world
    for node in [n for n in world.node_tree.nodes if n.bl_idname == "ShaderNodeTexEnvironment"]:
        world.node_tree.nodes.remove(node)
    env = use_image(world, float_image(bpy_module, "sun_sky", image_of(sun_sky_light(order), 64, 128)))
    api.project_world(lit_scene, order)
    obj = bake_sphere(bpy_module, order)
    lit_scene.prt_display.albedo_source = "WHITE"
    normals = local_positions(obj.data)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    before = api.shade(obj, lit_scene)
    assert normals[np.argmax(before[:, 0])] @ np.array([1.0, 0.0, 0.0]) > 0.95
    add_mapping(world, env, euler=(0.0, 0.0, math.pi / 2))
    values = api.shade(obj, lit_scene)
    assert normals[np.argmax(values[:, 0])] @ np.array([0.0, -1.0, 0.0]) > 0.95
    image = api.render_view(lit_scene, 128, 128)
    got, visible = sample_at_vertices(bpy_module, obj, lit_scene, image)
    want = values[visible]
    err = np.abs(got - want) / (np.abs(want) + 0.05)
    assert np.median(err) < 0.01, np.median(err)


def test_object_rotation_equals_opposite_lighting_rotation(bpy_module, lit_scene):
    """Object rotated by Euler e, lighting fixed == object fixed, world rotated by R(e)^-1 (a POINT
    Mapping node with the same Euler e, since the world is image(R d)): identical shading."""
    import prt_addon.api as api

    order = 5
    euler = (0.7, -0.4, 1.9)
    obj = bake_sphere(bpy_module, order, segments=24, rings=12)
    set_light(lit_scene, sun_sky_light(order))
    lit_scene.prt_display.albedo_source = "WHITE"
    obj.rotation_euler = euler
    bpy_module.context.view_layer.update()
    rotated_object = api.shade(obj, lit_scene)
    img_obj = api.render_view(lit_scene, 256, 256)
    got_obj, vis_obj = sample_at_vertices(bpy_module, obj, lit_scene, img_obj)

    obj.rotation_euler = (0.0, 0.0, 0.0)
    bpy_module.context.view_layer.update()
    unrotated = api.shade(obj, lit_scene)
    bpy_module.ops.prt.set_light_rotation(rotation=euler)
    rotated_light = api.shade(obj, lit_scene)
    img_light = api.render_view(lit_scene, 256, 256)
    got_light, vis_light = sample_at_vertices(bpy_module, obj, lit_scene, img_light)

    assert np.abs(rotated_object - unrotated).max() > 0.3  # the rotation matters
    np.testing.assert_allclose(rotated_light, rotated_object, rtol=1e-5, atol=1e-5)
    # And on the GPU: each configuration's image agrees with that same per-vertex shading.
    for got, vis in ((got_obj, vis_obj), (got_light, vis_light)):
        want = rotated_object[vis]
        assert np.median(np.abs(got - want) / (want + 0.05)) < 0.02


def test_world_projection_seam(bpy_module, lit_scene):
    """With no override the display reads world_projection.current_world_coeffs: a constant
    colour world c lights an unshadowed sphere to radiance c everywhere (white furnace)."""
    import prt_addon.api as api
    from prt_addon.blender.scene import lighting
    from prt_addon.blender.world import projection as world_projection

    world = bpy_module.data.worlds.new("Const")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.3, 0.5, 0.7, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
    lit_scene.world = world
    lighting.set_light_override(lit_scene, None)
    world_projection.project_and_store(lit_scene, 3)
    obj = bake_sphere(bpy_module, 3, segments=16, rings=8)
    np.testing.assert_allclose(
        api.shade(obj, lit_scene), np.tile([0.3, 0.5, 0.7], (len(obj.data.vertices), 1)), rtol=1e-3
    )
