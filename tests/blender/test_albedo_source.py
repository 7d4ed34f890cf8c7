"""Reading a material's albedo source: constant, image on a UV map through Multiply, colour attribute, fallbacks."""

import pytest


def _material(bpy, name):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    return mat, mat.node_tree, mat.node_tree.nodes["Principled BSDF"]


def test_albedo_source_reads_image_uv_and_multiply(empty_scene):
    import bpy

    from prt_addon.blender.scene.albedo_source import albedo_source

    mat, tree, bsdf = _material(bpy, "tex")
    image = bpy.data.images.new("tex_img", 4, 4)
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    uv = tree.nodes.new("ShaderNodeUVMap")
    uv.uv_map = "second"
    tree.links.new(uv.outputs["UV"], tex.inputs["Vector"])
    mix = tree.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.blend_type = "MULTIPLY"
    mix.inputs[0].default_value = 0.5
    mix.inputs[7].default_value = (0.2, 1.0, 0.6, 1.0)
    tree.links.new(tex.outputs["Color"], mix.inputs[6])
    tree.links.new(mix.outputs[2], bsdf.inputs["Base Color"])
    src = albedo_source(mat)
    assert src.kind == "IMAGE" and src.image == image and src.uv_map == "second"
    assert src.colour == pytest.approx((0.6, 1.0, 0.8))  # (1 - f) + f k
    assert src.note == ""


def test_albedo_source_attribute_constant_and_fallback(empty_scene):
    import bpy

    from prt_addon.blender.scene.albedo_source import albedo_source

    mat, tree, bsdf = _material(bpy, "attr")
    attr = tree.nodes.new("ShaderNodeVertexColor")
    attr.layer_name = "Col"
    tree.links.new(attr.outputs["Color"], bsdf.inputs["Base Color"])
    src = albedo_source(mat)
    assert src.kind == "ATTRIBUTE" and src.attribute == "Col"

    mat2, tree2, bsdf2 = _material(bpy, "const")
    bsdf2.inputs["Base Color"].default_value = (0.1, 0.2, 0.3, 1.0)
    assert albedo_source(mat2).colour == pytest.approx((0.1, 0.2, 0.3))

    mat3, tree3, bsdf3 = _material(bpy, "noise")
    mat3.diffuse_color = (0.3, 0.4, 0.5, 1.0)
    noise = tree3.nodes.new("ShaderNodeTexNoise")
    tree3.links.new(noise.outputs["Color"], bsdf3.inputs["Base Color"])
    src3 = albedo_source(mat3)
    assert src3.kind == "CONSTANT" and src3.colour == pytest.approx((0.3, 0.4, 0.5))
    assert "ShaderNodeTexNoise" in src3.note


def test_image_pixels_colour_spaces_and_missing(empty_scene):
    import bpy
    import numpy as np

    from prt_addon.blender.scene.albedo_source import image_pixels

    byte = bpy.data.images.new("byte_srgb", 2, 1)
    byte.pixels.foreach_set(np.array([0.5, 0.04, 1.0, 1.0, 0.0, 0.2, 0.7, 1.0], dtype=np.float32))
    rgb, note = image_pixels(byte)
    stored = np.array(byte.pixels[:], dtype=np.float64).reshape(1, 2, 4)[..., :3]  # bytes / 255
    expected = np.where(stored <= 0.04045, stored / 12.92, ((stored + 0.055) / 1.055) ** 2.4)
    assert np.allclose(rgb, expected, atol=1e-6) and note == ""

    flt = bpy.data.images.new("float_lin", 1, 1, float_buffer=True)
    flt.pixels.foreach_set(np.array([2.0, -0.5, 0.25, 1.0], dtype=np.float32))
    rgb, note = image_pixels(flt)
    assert np.allclose(rgb[0, 0], (1.0, 0.0, 0.25)) and "clamped" in note

    missing = bpy.data.images.new("missing", 1, 1)
    missing.source = "FILE"
    missing.filepath = "/nonexistent/albedo.png"
    missing.reload()
    assert image_pixels(missing)[0] is None
