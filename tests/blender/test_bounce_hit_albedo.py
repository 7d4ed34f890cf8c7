"""Bounced light off an image-textured single-quad wall: the albedo at each hit, so a red/blue
wall bounces red by its red half and blue by its blue half, as two quads of constant colour do."""

import warnings

import numpy as np
import pytest
from helpers.rooms import diffuse_material, grid

from prt_addon import api
from prt_addon.core.trace import raytrace

pytestmark = pytest.mark.skipif(not raytrace.EMBREE_AVAILABLE, reason="embreex not available")

RED, BLUE = (0.8, 0.1, 0.1), (0.1, 0.1, 0.8)


def _wall(bpy, name, y_range, material):
    """A single quad at x = -2 facing +x, 4 high, spanning y_range, u along y."""
    y0, y1 = y_range
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([(-2, y0, 0), (-2, y1, 0), (-2, y1, 4), (-2, y0, 4)], [], [(0, 1, 2, 3)])
    mesh.uv_layers.new(name="UVMap")
    co = np.array([mesh.vertices[i].co[:] for i in (lp.vertex_index for lp in mesh.loops)])
    # u from 0.07 to 0.93 (0.5 at y = 0): over half a texel inside the 8-texel image's edges, where
    # Linear and Repeat would blend in the other side's colour.
    uv = np.stack([0.07 + 0.86 * (co[:, 1] + 2.0) / 4.0, 0.07 + 0.86 * co[:, 2] / 4.0], axis=1).astype(np.float32)
    mesh.uv_layers[0].data.foreach_set("uv", uv.ravel())
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _room(bpy, scene, textured):
    world = bpy.data.worlds.new("white")
    scene.world = world
    with warnings.catch_warnings():  # (deprecated in Blender 5, still needed in 4.2)
        warnings.simplefilter("ignore", DeprecationWarning)
        world.use_nodes = True
    world.node_tree.nodes["Background"].inputs[0].default_value = (1.0, 1.0, 1.0, 1.0)
    floor = grid(bpy, "floor", (0, 0, 0), (0, 0, 0), diffuse_material(bpy, "white", (0.8, 0.8, 0.8)))
    if textured:
        image = bpy.data.images.new("halves", 8, 8, float_buffer=True)
        pixels = np.ones((8, 8, 4), np.float32)
        pixels[:, :4, :3], pixels[:, 4:, :3] = RED, BLUE  # (u < 0.5: red)
        image.pixels.foreach_set(pixels.ravel())
        material = diffuse_material(bpy, "halves", (1.0, 1.0, 1.0))
        node = material.node_tree.nodes.new("ShaderNodeTexImage")
        node.image = image
        bsdf = material.node_tree.nodes["Diffuse BSDF"]
        material.node_tree.links.new(node.outputs["Color"], bsdf.inputs["Color"])
        _wall(bpy, "wall", (-2.0, 2.0), material)
    else:
        _wall(bpy, "wall_red", (-2.0, 0.0), diffuse_material(bpy, "red", RED))
        _wall(bpy, "wall_blue", (0.0, 2.0), diffuse_material(bpy, "blue", BLUE))
    return floor


def _floor_bounce(bpy, scene, textured):
    from prt_addon.blender.scene import storage

    floor = _room(bpy, scene, textured)
    api.project_world(scene, 2)
    report = api.bake([floor], order=2, samples=256, bounces=1)
    bounce = storage.read_bounce(floor.data)[:, :, 0].astype(np.float64)  # (P, 3) band 0 per channel
    co = np.array([v.co[:] for v in floor.data.vertices])
    near = co[:, 0] < -1.0
    return report, bounce[near & (co[:, 1] < -0.7)].mean(axis=0), bounce[near & (co[:, 1] > 0.7)].mean(axis=0)


def test_a_textured_quad_wall_bounces_its_image_per_hit(bpy_module, empty_scene):
    bpy = bpy_module
    report, left, right = _floor_bounce(bpy, empty_scene, textured=True)
    assert report.bounce_channels == 3
    assert any("'halves': bounced light uses the image at each hit" in n for n in report.albedo_notes)
    assert left[0] > 3.0 * left[2] and right[2] > 3.0 * right[0]  # red by the red half, blue by the blue
    bpy.ops.wm.read_factory_settings(use_empty=True)
    _, left_ref, right_ref = _floor_bounce(bpy, bpy.context.scene, textured=False)
    # The one quad's bounce nodes are not the two quads' (green, the same albedo everywhere,
    # differs by 4-6 %); the triangles' image means instead of the image per hit were 30 % to 3.7x off.
    np.testing.assert_allclose(left, left_ref, rtol=0.08)
    np.testing.assert_allclose(right, right_ref, rtol=0.08)
