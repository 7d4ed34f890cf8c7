"""What the display's albedo falls back to, and says, for each bad input: a missing image file, a
packed image, UDIM tiles, Non-Color data, values outside 0 to 1, no node tree, unsupported nodes,
no UV map, a UV Map node naming a map the mesh lacks."""

import numpy as np
import pytest
from helpers import albedo_scenes
from helpers.panels import RecordingLayout, labels

VIEWPORT = (0.25, 0.5, 0.75)


def _plane(bpy, material, uv=True):
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    obj = bpy.context.active_object
    if not uv:
        obj.data.uv_layers.remove(obj.data.uv_layers[0])
    obj.data.materials.append(material)
    material.diffuse_color = (*VIEWPORT, 1.0)
    return obj


def _image_plane(bpy, image, uv=True, uv_map=None):
    return _plane(bpy, albedo_scenes.image_material(bpy, "mat", image, uv_map), uv)


def _only(obj):
    from prt_addon.blender.display.albedo_texture import notes
    from prt_addon.blender.scene.albedo_source import slot_sources

    (src,) = slot_sources(obj)
    return src, notes(obj)


def _viewport_fallback(src, says):
    assert src.kind == "CONSTANT" and src.colour == pytest.approx(VIEWPORT)
    assert len(says) == 1 and "viewport colour is used" in says[0] and says[0] == src.note
    return says[0]


def test_missing_image_file_draws_the_viewport_colour(bpy_module, empty_scene, tmp_path):
    image = bpy_module.data.images.new("gone", 4, 4)
    image.source = "FILE"
    image.filepath = str(tmp_path / "gone.png")
    image.reload()
    note = _viewport_fallback(*_only(_image_plane(bpy_module, image)))
    assert "'gone' has no pixels" in note


def test_packed_image_is_read(bpy_module, empty_scene, tmp_path):
    from prt_addon.blender.scene.albedo_source import image_pixels

    path = albedo_scenes.halves_png(str(tmp_path))
    image = bpy_module.data.images.load(path)
    image.pack()
    (tmp_path / "halves.png").unlink()  # only the packed copy is left
    image.reload()
    src, says = _only(_image_plane(bpy_module, image))
    assert src.kind == "IMAGE" and src.uv_map == "UVMap" and says == []
    rgb, note = image_pixels(image)
    assert note == "" and np.allclose(rgb[0, 0], (1.0, 0.0, 0.0)) and np.allclose(rgb[0, -1], (0.0, 0.0, 1.0))


def test_udim_tiles_draw_the_viewport_colour(bpy_module, empty_scene):
    image = bpy_module.data.images.new("tiles", 4, 4, tiled=True)
    note = _viewport_fallback(*_only(_image_plane(bpy_module, image)))
    assert "UDIM" in note


def test_non_color_image_is_used_as_it_is_and_told(bpy_module, empty_scene):
    from prt_addon.blender.scene.albedo_source import image_pixels

    image = bpy_module.data.images.new("data", 1, 1)
    image.colorspace_settings.name = "Non-Color"
    image.pixels.foreach_set(np.array([0.5, 0.25, 1.0, 1.0], dtype=np.float32))
    src, says = _only(_image_plane(bpy_module, image))
    assert src.kind == "IMAGE" and len(says) == 1 and "Non-Color" in says[0]
    rgb, _note = image_pixels(image)
    assert np.allclose(rgb[0, 0], np.round(np.array([0.5, 0.25, 1.0]) * 255) / 255, atol=1e-6)  # no sRGB curve


def test_values_outside_0_1_are_clamped_and_told(bpy_module, empty_scene):
    from prt_addon.blender.scene.albedo_source import image_pixels

    image = bpy_module.data.images.new("hdr", 1, 1, float_buffer=True)
    image.pixels.foreach_set(np.array([3.0, -1.0, 0.5, 1.0], dtype=np.float32))
    src, says = _only(_image_plane(bpy_module, image))
    assert src.kind == "IMAGE" and says == []  # (told once the display read the image: tests/gpu)
    rgb, note = image_pixels(image)
    assert np.allclose(rgb[0, 0], (1.0, 0.0, 0.5)) and "clamped" in note


def test_no_node_tree_draws_the_viewport_colour(bpy_module, empty_scene):
    material = bpy_module.data.materials.new("plain")
    if material.node_tree is not None:
        material.node_tree.nodes.clear()  # (Blender 5: a new material has a tree; no output node)
    src, says = _only(_plane(bpy_module, material))
    assert src.kind == "CONSTANT" and src.colour == pytest.approx(VIEWPORT) and says == []


def test_unsupported_nodes_draw_the_viewport_colour_and_tell(bpy_module, empty_scene):
    mat = albedo_scenes.image_material(bpy_module, "noisy", bpy_module.data.images.new("x", 2, 2))
    tree = mat.node_tree
    noise = tree.nodes.new("ShaderNodeTexNoise")
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    tree.links.new(noise.outputs["Color"], bsdf.inputs["Base Color"])
    note = _viewport_fallback(*_only(_plane(bpy_module, mat)))
    assert "ShaderNodeTexNoise" in note


@pytest.mark.parametrize("uv_map", [None, "elsewhere"])
def test_no_uv_map_draws_the_viewport_colour_and_tells(bpy_module, empty_scene, uv_map):
    image = bpy_module.data.images.new("checker", 2, 2)
    obj = _image_plane(bpy_module, image, uv=uv_map is not None, uv_map=uv_map)
    note = _viewport_fallback(*_only(obj))
    assert "no UV map" in note and (uv_map is None or "'elsewhere'" in note)


def test_display_panel_says_why_an_image_is_not_drawn(bpy_module, empty_scene, tmp_path):
    import types

    from helpers.display_scenes import write_bake

    from prt_addon.blender.ui import panels

    image = bpy_module.data.images.new("gone", 4, 4)
    image.source = "FILE"
    image.filepath = str(tmp_path / "gone.png")
    obj = _image_plane(bpy_module, image)
    write_bake(obj, np.zeros((4, 9)), 3)
    log = []
    context = types.SimpleNamespace(scene=empty_scene, active_object=obj, region=types.SimpleNamespace(width=2000))
    panels.VIEW3D_PT_prt_display.draw(types.SimpleNamespace(layout=RecordingLayout(log)), context)
    log = labels(log)
    assert any("'gone' has no pixels" in line and "viewport colour is used" in line for line in log), log
