"""An image on Base Color drawn per pixel by render_view: a red/blue image's halves where its UVs put them, beside an untextured slot."""

import math

import numpy as np
import pytest
from helpers import albedo_scenes
from helpers.display_scenes import add_camera, clamped_cosine_rows, set_light, write_bake
from helpers.specular_scenes import principled_material

SKY = np.array([0.6, 0.5, 0.4])  # constant sky radiance: E/pi of an open upward face is SKY


def _grid(bpy, scene, tmp_path, order, domain, uv_map):
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=8, y_subdivisions=8, size=2.0)
    obj = bpy.context.active_object
    if uv_map is not None:
        obj.data.uv_layers.new(name=uv_map)  # a copy of the first one, not the active render map
        obj.data.uv_layers[0].data.foreach_set("uv", np.zeros(2 * len(obj.data.loops), dtype=np.float32))
    image = bpy.data.images.load(albedo_scenes.halves_png(str(tmp_path)))
    obj.data.materials.append(albedo_scenes.image_material(bpy, "halves", image, uv_map, multiply=(0.5, 1.0, 0.8)))
    obj.data.materials.append(principled_material(bpy, "green", (0.0, 0.7, 0.0), 0.5, 0.0))
    centres = np.empty(3 * len(obj.data.polygons), dtype=np.float32)
    obj.data.polygons.foreach_get("center", centres)
    slots = (centres.reshape(-1, 3)[:, 1] > 0.0).astype(np.int32)  # the far half (top of the picture): green
    obj.data.polygons.foreach_set("material_index", slots)
    n = len(obj.data.vertices) if domain == "POINT" else len(obj.data.loops)
    write_bake(obj, clamped_cosine_rows(np.tile([0.0, 0.0, 1.0], (n, 1)), order), order, domain)
    light = np.zeros((order * order, 3))
    light[0] = SKY * math.sqrt(4.0 * math.pi)
    set_light(scene, light)
    add_camera(bpy, scene, location=(0.0, 0.0, 4.0), euler=(0.0, 0.0, 0.0), size=64)
    scene.camera.data.type = "ORTHO"
    scene.camera.data.ortho_scale = 2.0
    bpy.context.view_layer.update()
    return obj


@pytest.mark.parametrize(
    ("order", "domain", "uv_map"), [(3, "POINT", None), (8, "POINT", "second"), (3, "CORNER", None)]
)
def test_image_halves_drawn_per_pixel(bpy_module, empty_scene, gpu_ready, tmp_path, order, domain, uv_map):
    from prt_addon.blender.display import offscreen

    scene = empty_scene
    _grid(bpy_module, scene, tmp_path, order, domain, uv_map)
    scene.prt_display.albedo_source = "WHITE"
    white = offscreen.render_view(scene)[..., :3]
    shade = white[32, 32]
    assert np.allclose(white[2:62, 2:62], shade, rtol=1e-4) and np.allclose(shade, SKY, rtol=0.02)  # E/pi = SKY
    scene.prt_display.albedo_source = "MATERIAL"
    image = offscreen.render_view(scene)[..., :3]
    bottom, top = image[36:62], image[2:28]  # (the picture's top row is the far edge, +Y)
    left, right = bottom[:, 6:26], bottom[:, 38:58]  # (within half a texel of u = 0, 0.5, 1 they mix)
    assert np.allclose(left, np.array([0.5, 0.0, 0.0]) * shade, rtol=0.01, atol=1e-4), left.mean(axis=(0, 1))
    assert np.allclose(right, np.array([0.0, 0.0, 0.8]) * shade, rtol=0.01, atol=1e-4), right.mean(axis=(0, 1))
    # Pixel 32's centre is u = 32.5 / 64: bilinear between texels 3 (red) and 4 (blue), 0.5625 of the way.
    mixed = np.array([0.5 * (1.0 - 0.5625), 0.0, 0.8 * 0.5625]) * shade
    assert np.allclose(bottom[:, 32], mixed, rtol=0.02, atol=1e-4), bottom[:, 32].mean(axis=0)
    assert np.allclose(top[:, 2:62], np.array([0.0, 0.7, 0.0]) * shade, rtol=0.01, atol=1e-4)


def _lit_plane(bpy, scene, material):
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    obj = bpy.context.active_object
    obj.data.materials.append(material)
    write_bake(obj, clamped_cosine_rows(np.tile([0.0, 0.0, 1.0], (4, 1)), 3), 3)
    light = np.zeros((9, 3))
    light[0] = SKY * math.sqrt(4.0 * math.pi)
    set_light(scene, light)
    add_camera(bpy, scene, location=(0.0, 0.0, 4.0), euler=(0.0, 0.0, 0.0), size=16)
    scene.camera.data.type = "ORTHO"
    scene.camera.data.ortho_scale = 2.0
    bpy.context.view_layer.update()
    return obj


@pytest.mark.parametrize("case", ["missing", "udim", "no_uv"])
def test_fallbacks_draw_the_viewport_colour(bpy_module, empty_scene, gpu_ready, tmp_path, case):
    from prt_addon.blender.display import offscreen
    from prt_addon.blender.display.albedo_texture import notes

    bpy = bpy_module
    if case == "missing":
        image = bpy.data.images.new("gone", 4, 4)
        image.source = "FILE"
        image.filepath = str(tmp_path / "gone.png")
        image.reload()
    else:
        image = bpy.data.images.new("img", 4, 4, tiled=case == "udim")
    material = albedo_scenes.image_material(bpy, "mat", image)
    material.diffuse_color = (0.2, 0.4, 0.6, 1.0)
    obj = _lit_plane(bpy, empty_scene, material)
    if case == "no_uv":
        obj.data.uv_layers.remove(obj.data.uv_layers[0])
    drawn = offscreen.render_view(empty_scene)[2:14, 2:14, :3]
    assert np.allclose(drawn, np.array([0.2, 0.4, 0.6]) * SKY, rtol=0.02)
    assert len(notes(obj)) == 1 and "viewport colour is used" in notes(obj)[0]


def test_values_outside_0_1_drawn_clamped_and_told(bpy_module, empty_scene, gpu_ready):
    from prt_addon.blender.display import offscreen
    from prt_addon.blender.display.albedo_texture import notes

    image = bpy_module.data.images.new("hdr", 1, 1, float_buffer=True)
    image.pixels.foreach_set(np.array([3.0, -1.0, 0.5, 1.0], dtype=np.float32))
    obj = _lit_plane(bpy_module, empty_scene, albedo_scenes.image_material(bpy_module, "mat", image))
    assert notes(obj) == []  # (not read yet)
    drawn = offscreen.render_view(empty_scene)[2:14, 2:14, :3]
    assert np.allclose(drawn, np.array([1.0, 0.0, 0.5]) * SKY, rtol=0.02, atol=1e-5)
    assert len(notes(obj)) == 1 and "clamped" in notes(obj)[0]


def test_colour_attribute_slot_beside_an_image_slot(bpy_module, empty_scene, gpu_ready, tmp_path):
    """A Color Attribute node on one slot's Base Color colours only that slot's faces (linear in x
    here, so Gouraud draws it exactly); the image slot beside it keeps its image."""
    from prt_addon.blender.display import offscreen

    bpy = bpy_module
    scene = empty_scene
    obj = _grid(bpy, scene, tmp_path, 3, "POINT", None)
    mesh = obj.data
    co = np.empty(3 * len(mesh.vertices), dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    x = co.reshape(-1, 3)[:, 0]
    mesh.color_attributes.new("Col", "FLOAT_COLOR", "POINT")
    colours = np.c_[(x + 1.0) / 2.0, np.full_like(x, 0.5), np.full_like(x, 0.25), np.ones_like(x)]
    mesh.attributes["Col"].data.foreach_set("color", colours.astype(np.float32).ravel())
    green = mesh.materials[1]
    tree = green.node_tree
    node = tree.nodes.new("ShaderNodeVertexColor")
    node.layer_name = "Col"
    tree.links.new(node.outputs["Color"], tree.nodes["Principled BSDF"].inputs["Base Color"])
    image = offscreen.render_view(scene)[..., :3]
    top = image[2:28, 2:62]
    u = (np.arange(2, 62) + 0.5) / 64.0  # x = 2u - 1 at the pixel centres: r = u
    expected = np.stack([u, np.full_like(u, 0.5), np.full_like(u, 0.25)], axis=1) * SKY
    assert np.allclose(top, expected[None], rtol=0.01, atol=1e-4), top.mean(axis=0)[::10]
    left = image[36:62, 6:26]
    assert np.allclose(left, np.array([0.5, 0.0, 0.0]) * SKY, rtol=0.02, atol=1e-4)


@pytest.mark.parametrize("extension", ["REPEAT", "EXTEND", "CLIP", "MIRROR"])
@pytest.mark.parametrize("interpolation", ["Linear", "Closest"])
def test_image_node_extension_and_interpolation(bpy_module, empty_scene, gpu_ready, tmp_path, extension, interpolation):
    """A quad whose u runs from -1 to 2 across the view: outside [0, 1] the image continues as the
    node's extension says; at the red/blue edge Linear mixes the two texels, Closest does not."""
    from prt_addon.blender.display import offscreen

    bpy, scene = bpy_module, empty_scene
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    obj = bpy.context.active_object
    uvs = np.empty(2 * len(obj.data.loops), dtype=np.float32)
    obj.data.uv_layers[0].data.foreach_get("uv", uvs)
    uvs[0::2] = 3.0 * uvs[0::2] - 1.0  # u = 1.5 x + 0.5 for x in [-1, 1]
    obj.data.uv_layers[0].data.foreach_set("uv", uvs)
    image = bpy.data.images.load(albedo_scenes.halves_png(str(tmp_path)))
    material = albedo_scenes.image_material(bpy, "halves", image)
    node = next(n for n in material.node_tree.nodes if n.bl_idname == "ShaderNodeTexImage")
    node.extension, node.interpolation = extension, interpolation
    obj.data.materials.append(material)
    write_bake(obj, clamped_cosine_rows(np.tile([0.0, 0.0, 1.0], (len(obj.data.vertices), 1)), 3), 3, "POINT")
    light = np.zeros((9, 3))
    light[0] = SKY * math.sqrt(4.0 * math.pi)
    set_light(scene, light)
    add_camera(bpy, scene, location=(0.0, 0.0, 4.0), euler=(0.0, 0.0, 0.0), size=64)
    scene.camera.data.type, scene.camera.data.ortho_scale = "ORTHO", 2.0
    bpy.context.view_layer.update()
    row = offscreen.render_view(scene)[16:48, :, :3].mean(axis=0) / SKY  # the albedo along u
    u = 1.5 * (-1.0 + (np.arange(64) + 0.5) / 32.0) + 0.5  # at each pixel column's centre
    texel = 1.0 / 8.0  # (the halves image is 8 texels wide)
    clear = np.abs(u / 0.5 - np.round(u / 0.5)) * 0.5 > texel  # over a texel from every strip edge
    assert clear.sum() > 20
    assert np.allclose(row[clear], albedo_scenes.expected_halves(u[clear], extension), atol=0.01), row[clear]
    # Beside the red/blue edge at u = 0.5, within half a texel: Linear mixes them, Closest not.
    edge = np.abs(u - 0.5) < texel / 2
    weight = np.clip((u[edge] * 8.0 - 0.5) - 3.0, 0.0, 1.0)  # bilinear weight of texel 4 (blue)
    if interpolation == "Closest":
        weight = (u[edge] >= 0.5).astype(float)
    mixed = np.stack([1.0 - weight, np.zeros_like(weight), weight], axis=-1)
    assert edge.sum() >= 2 and np.allclose(row[edge], mixed, atol=0.02), (row[edge], mixed)
