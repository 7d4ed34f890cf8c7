"""Live PRT display against api.shade: shaders per order, the offscreen render, materials, per-corner bakes.

Needs the GPU initialised headless. The helpers and lit_scene below serve the other display tests too.

Baked data is written here by a test helper that follows docs/storage.md exactly (unshadowed
transfer of a sphere = the clamped cosine about the local normal), independent of the bake.
"""

import math
import warnings

import numpy as np
import pytest
from helpers.display_scenes import (
    bake_sphere,
    clamped_cosine_rows,
    local_positions,
    sample_at_vertices,
    set_light,
    sun_sky_light,
    write_bake,
)

# ---------------------------------------------------------------------------------------------
# Helpers
# ---------------------------------------------------------------------------------------------


# ---------------------------------------------------------------------------------------------
# Fixtures
# ---------------------------------------------------------------------------------------------


# ---------------------------------------------------------------------------------------------
# Tests
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("order", [1, 2, 3, 4, 7, 8, 12, 16])
def test_shader_compiles_for_every_order(gpu_ready, order):
    from prt_addon.blender.display import shader as display_shader
    from prt_addon.blender.scene import storage

    count = storage.attribute_count(order)
    shader = display_shader.get_shader(count)
    assert shader is not None
    # Orders 1..6 fit in vertex attributes (pos, albedo, normal, contact tangent + 12); 7 and up use the texture path.
    assert display_shader.shader_mode(count) == ("ATTR" if order <= 6 else "TEXTURE")


@pytest.mark.parametrize("domain", ["POINT", "TEXEL"])
@pytest.mark.parametrize(
    ("textured", "specular", "spec_maps"), [(False, False, False), (True, False, False), (True, True, True)]
)
def test_push_constants_fit_what_every_backend_guarantees(gpu_ready, capfd, domain, textured, specular, spec_maps):
    """Every variant's push constants fit Blender's guaranteed 128 bytes: Blender prints a warning
    while the create-info is built otherwise (a texel bake with an albedo image did, at 136)."""
    from prt_addon.blender.display import shader as display_shader

    capfd.readouterr()
    for lights in (None, (1, 2)):
        display_shader.clear_shaders()
        display_shader.get_shader(4, lights, domain=domain, textured=textured, specular=specular, spec_maps=spec_maps)
    out, err = capfd.readouterr()
    assert "Push constants" not in out + err, out + err


def test_shade_matches_world_frame_expectation(bpy_module, lit_scene):
    """shade() of a rotated, translated, uniformly scaled sphere equals the clamped-cosine
    convolution of the world light at each world normal, computed without the local frame."""
    import prt_addon.api as api

    order = 4
    obj = bake_sphere(bpy_module, order, segments=16, rings=8)
    obj.rotation_euler = (0.4, -1.1, 2.3)
    obj.location = (0.3, 0.2, -0.1)
    obj.scale = (1.7, 1.7, 1.7)
    bpy_module.context.view_layer.update()
    light = sun_sky_light(order)
    set_light(lit_scene, light)
    got = api.shade(obj, lit_scene)
    r = np.array(obj.matrix_world.to_3x3().normalized())
    n_local = local_positions(obj.data)
    n_world = (n_local / np.linalg.norm(n_local, axis=1, keepdims=True)) @ r.T
    expected = np.maximum(clamped_cosine_rows(n_world, order) @ light, 0.0)
    assert got.shape == (len(obj.data.vertices), 3)
    np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-6)
    # Non-uniform scale does not change the shading (only the rotation part is used).
    obj.scale = (0.5, 2.0, 1.3)
    bpy_module.context.view_layer.update()
    np.testing.assert_allclose(api.shade(obj, lit_scene), got, rtol=1e-5, atol=1e-6)
    # A mirrored object: the orthogonal part is a reflection, handled by the SH parity.
    obj.scale = (-1.0, 1.0, 1.0)
    bpy_module.context.view_layer.update()
    m = np.array(obj.matrix_world.to_3x3())
    n_mirror = (n_local / np.linalg.norm(n_local, axis=1, keepdims=True)) @ m.T
    expected_mirror = np.maximum(clamped_cosine_rows(n_mirror, order) @ light, 0.0)
    np.testing.assert_allclose(api.shade(obj, lit_scene), expected_mirror, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("order", [3, 8, 16])
def test_offscreen_render_agrees_with_shade(bpy_module, lit_scene, order):
    """The GPU image at each visible vertex equals api.shade there (order 3: vertex attributes,
    orders 8 and 16: transfer texture)."""
    import prt_addon.api as api

    obj = bake_sphere(bpy_module, order)
    obj.rotation_euler = (0.3, 0.2, 0.7)  # the local frame is not the world frame
    light = sun_sky_light(order)
    set_light(lit_scene, light)
    lit_scene.prt_display.albedo_source = "WHITE"
    image = api.render_view(lit_scene, 512, 512)
    assert image.shape == (512, 512, 4)
    assert image.dtype == np.float32
    expected = api.shade(obj, lit_scene)
    got, visible = sample_at_vertices(bpy_module, obj, lit_scene, image)
    assert visible.sum() > 200
    want = expected[visible]
    err = np.abs(got - want) / (np.abs(want) + 0.05)
    assert np.median(err) < 0.01, np.median(err)
    assert err.max() < 0.05, err.max()
    # Background stays transparent, the sphere is opaque.
    assert image[0, 0, 3] == 0.0
    assert image[256, 256, 3] == 1.0


def test_material_albedo_multiplies(bpy_module, lit_scene):
    import prt_addon.api as api

    obj = bake_sphere(bpy_module, 3, segments=24, rings=12)
    mat = bpy_module.data.materials.new("Red")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        mat.use_nodes = True
    mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.5, 0.25, 0.1, 1.0)
    obj.data.materials.append(mat)
    set_light(lit_scene, sun_sky_light(3))
    lit_scene.prt_display.albedo_source = "WHITE"
    white = api.render_view(lit_scene, 128, 128)
    lit_scene.prt_display.albedo_source = "MATERIAL"
    red = api.render_view(lit_scene, 128, 128)
    mask = white[..., 3] > 0
    np.testing.assert_allclose(red[mask, :3], white[mask, :3] * [0.5, 0.25, 0.1], rtol=1e-5, atol=1e-6)


def test_corner_domain_flat_faces(bpy_module, lit_scene):
    """A flat-shaded cube baked per corner: every face is uniform and equals shade() there."""
    import bmesh

    import prt_addon.api as api

    mesh = bpy_module.data.meshes.new("Cube")
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=2.0)
    bm.to_mesh(mesh)
    bm.free()
    obj = bpy_module.data.objects.new("Cube", mesh)
    lit_scene.collection.objects.link(obj)
    obj.rotation_euler = (0.0, 0.0, math.radians(35))
    order = 3
    loop_poly = np.repeat(np.arange(len(mesh.polygons)), [p.loop_total for p in mesh.polygons])
    fn = np.empty(len(mesh.polygons) * 3, dtype=np.float32)
    mesh.polygons.foreach_get("normal", fn)
    write_bake(obj, clamped_cosine_rows(fn.reshape(-1, 3)[loop_poly], order), order, "CORNER")
    set_light(lit_scene, sun_sky_light(order))
    lit_scene.prt_display.albedo_source = "WHITE"
    values = api.shade(obj, lit_scene)
    assert values.shape == (len(mesh.loops), 3)
    image = api.render_view(lit_scene, 256, 256)
    # Camera along +Y: the faces with world normals -X rotated (35 deg) and -Y rotated are seen.
    mw = np.array(obj.matrix_world)
    depsgraph = bpy_module.context.evaluated_depsgraph_get()
    cam = lit_scene.camera
    vp = np.array(cam.calc_matrix_camera(depsgraph, x=256, y=256)) @ np.array(cam.matrix_world.inverted())
    seen = 0
    for poly in mesh.polygons:
        n_world = mw[:3, :3] @ np.array(poly.normal)
        if n_world[1] > -0.3:
            continue
        centre = mw @ np.r_[np.array(poly.center), 1.0]
        clip = vp @ centre
        col = int((clip[0] / clip[3] + 1) * 128)
        row = int((1 - clip[1] / clip[3]) * 128)
        np.testing.assert_allclose(image[row, col, :3], values[poly.loop_start], rtol=1e-4)
        seen += 1
    assert seen == 2


def test_texture_path_with_several_materials(bpy_module, lit_scene):
    """Per-material index buffers of the second slot start at a high vertex index (Blender may
    store them as 16-bit indices plus a base vertex): gl_VertexID must still be the element."""
    import prt_addon.api as api

    order = 8
    obj = bake_sphere(bpy_module, order, segments=64, rings=32)
    obj.rotation_euler = (0.1, 0.2, 0.3)
    colours = [(1.0, 1.0, 1.0, 1.0), (0.5, 0.5, 0.5, 1.0)]
    for i, colour in enumerate(colours):
        mat = bpy_module.data.materials.new(f"M{i}")
        mat.diffuse_color = colour
        if mat.node_tree is not None:
            mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = colour
        obj.data.materials.append(mat)
    centres = np.empty(len(obj.data.polygons) * 3, dtype=np.float32)
    obj.data.polygons.foreach_get("center", centres)
    upper = (centres.reshape(-1, 3)[:, 2] > 0.0).astype(np.int32)
    obj.data.polygons.foreach_set("material_index", 1 - upper)  # slot 1 = lower half
    obj.data.update()
    set_light(lit_scene, sun_sky_light(order))
    lit_scene.prt_display.albedo_source = "MATERIAL"
    image = api.render_view(lit_scene, 512, 512)
    expected = api.shade(obj, lit_scene)
    z = local_positions(obj.data)[:, 2]
    got, visible = sample_at_vertices(bpy_module, obj, lit_scene, image)
    zv = z[visible]
    keep = np.abs(zv) > 0.1  # away from the seam between the two materials
    tint = np.where(zv[keep] > 0, 1.0, 0.5)[:, None]
    want = expected[visible][keep] * tint
    err = np.abs(got[keep] - want) / (want + 0.05)
    assert (zv[keep] < 0).sum() > 50
    assert (zv[keep] > 0).sum() > 50
    assert np.median(err) < 0.01 and err.max() < 0.05, (np.median(err), err.max())
