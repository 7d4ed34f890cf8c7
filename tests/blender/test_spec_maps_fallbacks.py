"""Which Roughness / Metallic / Specular IOR Level / IOR links are read as images, and what each bad input falls back to and says: a missing file, a packed image, UDIM tiles, an sRGB image, values outside 0 to 1, no node tree, other nodes, no UV map, two UV maps."""

import numpy as np
import pytest
from helpers import spec_map_scenes as maps
from helpers.albedo_scenes import halves_png, image_material
from helpers.panels import RecordingLayout, labels


def _plane(bpy, material, uv=True):
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    obj = bpy.context.active_object
    if not uv:
        obj.data.uv_layers.remove(obj.data.uv_layers[0])
    obj.data.materials.append(material)
    return obj


def _read(bpy, material, uv=True):
    from prt_addon.blender.display.material_maps import notes
    from prt_addon.blender.scene.principled_maps import mesh_maps

    obj = _plane(bpy, material, uv)
    return mesh_maps(material, obj.data), notes(obj)


def _linked(bpy, image, socket="Roughness", output="Color"):
    mat, bsdf = maps.principled(bpy, "mat")
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    mat.node_tree.links.new(tex.outputs[output], bsdf.inputs[socket])
    return mat, tex, bsdf


def _data_image(bpy, name="data", size=2):
    image = bpy.data.images.new(name, size, size)
    image.colorspace_settings.name = "Non-Color"
    return image


def test_the_links_read(bpy_module, empty_scene):
    """Separate Color's Green and Blue (a metallic-roughness map), an image's Color (its luminance)
    and Alpha, through Math Multiply by a constant; each map on the mesh's UV map."""
    from prt_addon.blender.scene.principled_maps import ALPHA, LUMINANCE

    bpy = bpy_module
    image = maps.orm_image(bpy)
    found, says = _read(bpy, maps.orm_material(bpy, image)[0])
    rough, metal, level, ior = found.inputs
    assert (rough.channel, metal.channel, level, ior) == (1, 2, None, None) and rough.image == image and says == []
    assert found.uv_map == "UVMap" and rough.uv_map == metal.uv_map == "UVMap"
    mat, _tex, bsdf = _linked(bpy, _data_image(bpy), "Specular IOR Level", "Alpha")
    math = mat.node_tree.nodes.new("ShaderNodeMath")
    math.operation = "MULTIPLY"
    math.inputs[1].default_value = 0.25
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    tex.interpolation, tex.extension = "Closest", "MIRROR"
    mat.node_tree.links.new(tex.outputs["Color"], math.inputs[0])
    mat.node_tree.links.new(math.outputs[0], bsdf.inputs["Metallic"])
    found, says = _read(bpy, mat)
    rough, metal, level, ior = found.inputs
    assert rough is None and ior is None and level.channel == ALPHA and says == []
    assert metal.channel == LUMINANCE and metal.factor == pytest.approx(0.25) and metal.sampling == (1, 3)


def test_the_pixels_read(bpy_module, empty_scene, tmp_path):
    """A channel as it is (Non-Color), the luminance of the colour, the sRGB curve on an sRGB
    image (with a note in the panel), the factor, and values outside 0 to 1 clamped and told."""
    from prt_addon.blender.scene.principled_maps import LUMINANCE, map_pixels

    bpy = bpy_module
    image = _data_image(bpy, size=1)
    image.pixels.foreach_set(np.array([0.2, 0.6, 1.0, 0.4], np.float32))
    byte = lambda x: np.round(np.array(x) * 255) / 255
    assert map_pixels(image, 1)[0][0, 0] == pytest.approx(byte(0.6), abs=1e-6)
    lum = byte([0.2, 0.6, 1.0]) @ np.array([0.2126, 0.7152, 0.0722])
    assert map_pixels(image, LUMINANCE, 0.5)[0][0, 0] == pytest.approx(0.5 * lum, abs=1e-6)
    srgb = bpy.data.images.new("srgb", 1, 1)
    srgb.pixels.foreach_set(np.array([0.5, 0.5, 0.5, 1.0], np.float32))
    value = float(byte(0.5))
    assert map_pixels(srgb, 0)[0][0, 0] == pytest.approx(((value + 0.055) / 1.055) ** 2.4, abs=1e-6)
    found, says = _read(bpy, _linked(bpy, srgb)[0])
    assert found.inputs[0] is not None and len(says) == 1 and "is sRGB" in says[0] and "Non-Color expected" in says[0]
    hdr = bpy.data.images.new("hdr", 1, 1, float_buffer=True)
    hdr.pixels.foreach_set(np.array([3.0, -1.0, 0.5, 1.0], np.float32))
    values, note = map_pixels(hdr, 0)
    assert values[0, 0] == 1.0 and map_pixels(hdr, 1)[0][0, 0] == 0.0 and "clamped" in note
    assert map_pixels(hdr, 0, upper=np.inf)[0][0, 0] == pytest.approx(3.0)  # (Specular IOR Level)


def test_an_ior_image_is_read_and_clamped_below_1(bpy_module, empty_scene):
    """IOR from an image's Red through Separate Color and Math Multiply by 4: the fourth input,
    its value the channel times 4, values below 1 clamped to 1 and told (none above)."""
    from prt_addon.blender.scene.principled_maps import RANGES, map_pixels

    bpy = bpy_module
    image = _data_image(bpy, size=2)
    image.pixels.foreach_set(
        np.repeat(np.array([[0.2, 0.0, 0.0, 1.0], [0.6, 0.0, 0.0, 1.0]], np.float32), 2, 0).ravel()
    )
    mat, bsdf = maps.principled(bpy, "ior")
    tree = mat.node_tree
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    sep = tree.nodes.new("ShaderNodeSeparateColor")
    math = tree.nodes.new("ShaderNodeMath")
    math.operation = "MULTIPLY"
    math.inputs[1].default_value = 4.0
    tree.links.new(tex.outputs["Color"], sep.inputs[0])
    tree.links.new(sep.outputs["Red"], math.inputs[0])
    tree.links.new(math.outputs[0], bsdf.inputs["IOR"])
    found, says = _read(bpy, mat)
    assert found.inputs[:3] == (None, None, None) and says == []
    ior = found.inputs[3]
    assert (ior.channel, ior.factor, ior.image) == (0, pytest.approx(4.0), image)
    values, note = map_pixels(image, ior.channel, ior.factor, RANGES[3][1], RANGES[3][0])
    byte = lambda x: np.round(np.array(x) * 255) / 255
    assert values[0, 0] == 1.0 and values[1, 0] == pytest.approx(4.0 * byte(0.6), abs=1e-5)
    assert note == "image 'data': values below 1 clamped"


def test_packed_image_is_read(bpy_module, empty_scene, tmp_path):
    from prt_addon.blender.scene.principled_maps import map_pixels

    bpy = bpy_module
    image = bpy.data.images.load(halves_png(str(tmp_path)))
    image.colorspace_settings.name = "Non-Color"
    image.pack()
    (tmp_path / "halves.png").unlink()
    image.reload()
    found, says = _read(bpy, _linked(bpy, image)[0])
    assert found.inputs[0] is not None and says == []
    red = map_pixels(image, 0)[0]
    assert red[0, 0] == 1.0 and red[0, -1] == 0.0


@pytest.mark.parametrize("socket", ["Roughness", "IOR"])
@pytest.mark.parametrize("case", ["missing", "udim", "no_image", "no_uv", "other_uv", "noise", "vector"])
def test_bad_inputs_draw_the_constant_and_tell(bpy_module, empty_scene, tmp_path, case, socket):
    bpy = bpy_module
    image = _data_image(bpy)
    if case == "missing":
        image = bpy.data.images.new("gone", 4, 4)
        image.source = "FILE"
        image.filepath = str(tmp_path / "gone.png")
        image.reload()
    elif case == "udim":
        image = bpy.data.images.new("tiles", 4, 4, tiled=True)
    mat, tex, bsdf = _linked(bpy, image, socket)
    tree = mat.node_tree
    if case == "no_image":
        tex.image = None
    elif case == "other_uv":
        uv = tree.nodes.new("ShaderNodeUVMap")
        uv.uv_map = "elsewhere"
        tree.links.new(uv.outputs["UV"], tex.inputs["Vector"])
    elif case == "noise":
        noise = tree.nodes.new("ShaderNodeTexNoise")
        tree.links.new(noise.outputs["Fac"], bsdf.inputs[socket])
    elif case == "vector":
        coords = tree.nodes.new("ShaderNodeTexCoord")
        tree.links.new(coords.outputs["Generated"], tex.inputs["Vector"])
    found, says = _read(bpy, mat, uv=case != "no_uv")
    assert found.inputs == (None, None, None, None) and len(says) == 1, says
    assert says[0].startswith(f"'mat' {socket}: ") and says[0].endswith("its constant is used")
    expected = {
        "missing": "'gone' has no pixels",
        "udim": "UDIM tiles are not read",
        "no_image": "has no image",
        "no_uv": "has no UV map",
        "other_uv": "has no UV map 'elsewhere'",
        "noise": "ShaderNodeTexNoise",
        "vector": "ShaderNodeTexCoord",
    }[case]
    assert expected in says[0]


def test_no_node_tree_and_other_shaders_have_no_maps(bpy_module, empty_scene):
    from prt_addon.blender.scene.principled_maps import principled_maps

    bpy = bpy_module
    plain = bpy.data.materials.new("plain")
    if plain.node_tree is not None:
        plain.node_tree.nodes.clear()
    assert not principled_maps(plain).any and principled_maps(plain).notes == ()
    assert not principled_maps(None).any
    diffuse = image_material(bpy, "diffuse", _data_image(bpy), shader="ShaderNodeBsdfDiffuse")
    assert not principled_maps(diffuse).any


def test_maps_on_another_uv_map_than_the_base_colour_fall_back(bpy_module, empty_scene):
    """One UV map per material is drawn: a roughness image on the second UV map while the base
    colour image is on the first draws the constant roughness, and says why."""
    from prt_addon.blender.display.material_maps import slot_maps
    from prt_addon.blender.scene.albedo_source import slot_sources

    bpy = bpy_module
    mat = image_material(bpy, "mat", _data_image(bpy, "base"))
    bsdf = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = _data_image(bpy, "rough")
    uv = mat.node_tree.nodes.new("ShaderNodeUVMap")
    uv.uv_map = "second"
    mat.node_tree.links.new(uv.outputs["UV"], tex.inputs["Vector"])
    mat.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Roughness"])
    obj = _plane(bpy, mat)
    obj.data.uv_layers.new(name="second")
    (found,) = slot_maps(obj, slot_sources(obj))
    assert not found.any and "on UV map 'second', the material's other image on 'UVMap'" in found.notes[0]


@pytest.mark.parametrize("specular", [False, True])
def test_display_panel_says_why_a_map_is_not_drawn(bpy_module, empty_scene, tmp_path, specular):
    """With Specular on, the Display panel says why a roughness image is drawn as its constant;
    with it off (no specular drawn) it says nothing of it."""
    import types

    from helpers.display_scenes import write_bake

    from prt_addon.blender.ui import panels

    bpy = bpy_module
    image = bpy.data.images.new("gone", 4, 4)
    image.source = "FILE"
    image.filepath = str(tmp_path / "gone.png")
    obj = _plane(bpy, _linked(bpy, image)[0])
    write_bake(obj, np.zeros((4, 9)), 3)
    empty_scene.prt_display.specular = specular
    log = []
    context = types.SimpleNamespace(scene=empty_scene, active_object=obj, region=types.SimpleNamespace(width=2000))
    panels.VIEW3D_PT_prt_display.draw(types.SimpleNamespace(layout=RecordingLayout(log)), context)
    log = labels(log)
    said = [line for line in log if "'gone' has no pixels" in line and "its constant is used" in line]
    assert bool(said) == specular, log
