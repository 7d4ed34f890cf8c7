"""Stiff lighting: HDR suns ring in SH. The default (no window, radiance clamped at 0 by
api.shade and the shader) must never show negative or non-finite radiance on the bundled sunny
HDRIs and on synthetic suns of 0.5 to 5 degrees at 1e4 to 1e6 on a dim background; the choice is
measured in docs/accuracy.md ("Stiff lighting").
"""

import math

import numpy as np
import pytest
from helpers.worlds import bundled_hdri_path

from prt_addon.core.sh import projection


def _scene(bpy, scene):
    """Suzanne (507 vertices, smooth) standing on a 16 x 16 ground grid, baked at order 8."""
    import bmesh

    from prt_addon import api

    objs = []
    for name in ("monkey", "ground"):
        bm = bmesh.new()
        if name == "monkey":
            bmesh.ops.create_monkey(bm)
            bmesh.ops.translate(bm, verts=bm.verts, vec=(0.0, 0.0, 0.9))
        else:
            bmesh.ops.create_grid(bm, x_segments=16, y_segments=16, size=4.0)
        mesh = bpy.data.meshes.new(name)
        bm.to_mesh(mesh)
        bm.free()
        mesh.shade_smooth()
        obj = bpy.data.objects.new(name, mesh)
        scene.collection.objects.link(obj)
        objs.append(obj)
    report = api.bake(objs, order=8, samples=512)
    assert report.ok
    return objs


def _world(bpy, scene, image):
    world = bpy.data.worlds.new("World")
    if world.node_tree is None:
        world.use_nodes = True
    tree = world.node_tree
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = image
    tree.links.new(env.outputs["Color"], tree.nodes["Background"].inputs["Color"])
    scene.world = world


def _sun_image(bpy, half_angle_deg, value, background=0.05, size=(2048, 1024)):
    """Equirect float image: a disk of angular radius half_angle (35 degrees up, azimuth 40) of
    radiance `value` on a dim uniform background."""
    w, h = size
    d = projection.pixel_directions(h, w)  # (h, w, 3), row 0 = nadir, as Image.pixels
    el, az = math.radians(35.0), math.radians(40.0)
    axis = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    inside = d @ axis >= math.cos(math.radians(half_angle_deg))
    assert inside.any()
    rgb = np.where(inside[..., None], value, background) * np.ones(3)
    image = bpy.data.images.new(f"sun{half_angle_deg}_{value:g}", w, h, float_buffer=True)
    image.pixels.foreach_set(np.concatenate([rgb, np.ones((h, w, 1))], 2).astype(np.float32).ravel())
    return image


def _check(objs, scene, order):
    """Shade at `order` (lighting projected at that order, transfer truncated by the display):
    finite and >= 0. Returns the unclamped minimum over the mean (to show the clamp matters)."""
    from prt_addon import api
    from prt_addon.blender.scene import storage
    from prt_addon.blender.world import projection as world_projection

    api.project_world(scene, order, split_lights=False)  # the SH path alone
    lowest = 0.0
    for obj in objs:
        r = api.shade(obj, scene)
        assert np.all(np.isfinite(r)), obj.name
        # Independent of the display code: the bake's own reader times the stored world lighting
        # (the objects are untransformed, so their local frame is the world frame).
        np.testing.assert_allclose(np.array(obj.matrix_world), np.eye(4), atol=1e-12)
        transfer = storage.read_transfer(obj.data).astype(np.float64)
        raw = transfer[:, : order * order] @ world_projection.current_world_coeffs(scene)[: order * order]
        assert np.all(np.isfinite(raw))
        scale = np.abs(raw).max()
        np.testing.assert_allclose(r, np.maximum(raw, 0.0), rtol=1e-5, atol=1e-6 * scale)  # no window: clamp only
        lowest = min(lowest, raw.min() / max(raw.mean(), 1e-30))
    return lowest


@pytest.fixture(scope="module")
def stiff_scene(bpy_module, addon):
    bpy_module.ops.wm.read_factory_settings(use_empty=True)
    return bpy_module.context.scene, _scene(bpy_module, bpy_module.context.scene)


@pytest.mark.parametrize("name", ["city", "sunrise", "sunset", "forest"])
def test_bundled_sunny_hdris_shade_non_negative_and_finite(bpy_module, stiff_scene, name):
    scene, objs = stiff_scene
    _world(bpy_module, scene, bpy_module.data.images.load(bundled_hdri_path(name), check_existing=True))
    lows = [_check(objs, scene, order) for order in (2, 4, 8)]
    if name in ("city", "sunrise"):
        assert min(lows) < 0.0  # these rings without the clamp: the clamp is doing the work


@pytest.mark.parametrize(("half_angle", "value"), [(0.5, 1e6), (1.0, 1e5), (5.0, 1e4), (5.0, 1e6)])
def test_synthetic_suns_shade_non_negative_and_finite(bpy_module, stiff_scene, half_angle, value):
    scene, objs = stiff_scene
    _world(bpy_module, scene, _sun_image(bpy_module, half_angle, value))
    lows = [_check(objs, scene, order) for order in (3, 8)]
    assert min(lows) < 0.0
