"""A Principled material whose Roughness and Metallic come from a metallic-roughness image, exported: the texture glTF carries (roughness in G, metallic in B) and the extras the plugin mixes the occlusion with."""

import numpy as np
import pytest
from helpers import spec_map_scenes as maps
from helpers.gltf import _read_glb

from prt_addon import api
from prt_addon.blender.export import glb


def _png_pixels(bpy, data, tmp_path):
    path = tmp_path / "exported.png"
    path.write_bytes(data)
    image = bpy.data.images.load(str(path))
    image.colorspace_settings.name = "Non-Color"
    px = np.empty(image.size[0] * image.size[1] * image.channels, np.float32)
    image.pixels.foreach_get(px)
    return px.reshape(image.size[1], image.size[0], image.channels)


def _export(bpy, scene, tmp_path, material, name):
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    obj = bpy.context.active_object
    obj.data.materials.append(material)
    api.bake([obj], order=2, samples=16)
    path = api.export_gltf(str(tmp_path / f"{name}.glb"), objects=[obj], scene=scene)
    bpy.data.objects.remove(obj)
    return path


def test_the_file_carries_the_map_and_the_two_lobes(bpy_module, empty_scene, tmp_path):
    bpy, scene = bpy_module, empty_scene
    scene.world = bpy.data.worlds.new("white")
    scene.prt_display.specular = True
    api.project_world(scene, 2)
    mapped, _tex = maps.orm_material(bpy, maps.orm_image(bpy))
    document, _accessor = _read_glb(_export(bpy, scene, tmp_path, mapped, "mapped"))
    (material,) = document["materials"]
    extras = material["extras"]["PRT_lighting"]
    assert extras["maps"] == ["roughness", "metallic"]
    assert extras["roughness_range"] == pytest.approx([0.2, 0.8], abs=1e-6)
    lobes = {}
    for roughness in (0.2, 0.8):
        constant = maps.principled(bpy, f"r{roughness}", roughness=roughness)[0]
        doc, _acc = _read_glb(_export(bpy, scene, tmp_path, constant, f"r{roughness}"))
        lobes[roughness] = doc["materials"][0]["extras"]["PRT_lighting"]
        assert "maps" not in lobes[roughness]
    # (the image's 8-bit 0.2 and 0.8 against the sockets' float32: bands 5e-6 apart)
    assert extras["lobe_bands"] == pytest.approx(lobes[0.2]["lobe_bands"], rel=1e-4)
    assert extras["lobe_bands2"] == pytest.approx(lobes[0.8]["lobe_bands"], rel=1e-4)
    assert extras["lobe_open2"] == pytest.approx(lobes[0.8]["lobe_open"], rel=1e-4)
    # The texture three.js samples: its G is the roughness image, its B the metallic one.
    texture = document["textures"][material["pbrMetallicRoughness"]["metallicRoughnessTexture"]["index"]]
    view = document["bufferViews"][document["images"][texture["source"]]["bufferView"]]
    binary = glb.read(str(tmp_path / "mapped.glb"))[1][0][1]
    start = view.get("byteOffset", 0)
    px = _png_pixels(bpy, binary[start : start + view["byteLength"]], tmp_path)
    half = maps.SIZE // 2
    for (u, v), (roughness, metallic) in maps.QUADRANTS.items():
        block = px[v * half : (v + 1) * half, u * half : (u + 1) * half]
        assert np.allclose(block[..., 1], roughness, atol=1 / 255) and np.allclose(
            block[..., 2], metallic, atol=1 / 255
        )


def test_level_and_ior_images_are_folded_into_one_f0_map(bpy_module, empty_scene, tmp_path):
    """A Specular IOR Level image (0 / 1 by halves of u, 64 px) and an IOR image (1.2 / 2.0 by halves,
    16 px, Closest) on the second UV map: the file's `f0_map` is 64 x 64 float16 texels, each
    ((IOR - 1) / (IOR + 1))^2 x 2 x level of its half (within float16's rounding), on TEXCOORD_1,
    sampled as the larger image's node; the glTF's own specularTexture is the level image as it
    is (its RGB, alpha 1: three.js's specularIntensityMap would read 1 everywhere)."""
    bpy, scene = bpy_module, empty_scene
    scene.world = bpy.data.worlds.new("white")
    scene.prt_display.specular = True
    api.project_world(scene, 2)
    material, bsdf = maps.socket_material(
        bpy, "folded", maps.halves_image(bpy, "levels", 0.0, 1.0), "Specular IOR Level"
    )
    tree = material.node_tree
    level_tex = bsdf.inputs["Specular IOR Level"].links[0].from_node
    ior_tex = tree.nodes.new("ShaderNodeTexImage")
    ior_tex.image = maps.halves_image(bpy, "iors", 1.2, 2.0, size=16)
    ior_tex.interpolation = "Closest"
    tree.links.new(ior_tex.outputs["Color"], bsdf.inputs["IOR"])
    uv = tree.nodes.new("ShaderNodeUVMap")
    uv.uv_map = "second"
    for tex in (level_tex, ior_tex):
        tree.links.new(uv.outputs["UV"], tex.inputs["Vector"])
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    obj = bpy.context.active_object
    obj.data.uv_layers.new(name="second")
    obj.data.materials.append(material)
    api.bake([obj], order=2, samples=16)
    path = api.export_gltf(str(tmp_path / "folded.glb"), objects=[obj], scene=scene)
    document, chunks = glb.read(path)
    (gltf_material,) = document["materials"]
    extras = gltf_material["extras"]["PRT_lighting"]
    assert extras["maps"] == ["specular_ior_level", "ior"]
    block = extras["f0_map"]
    assert (block["width"], block["height"], block["format"]) == (64, 64, "float16_r")
    assert (block["texCoord"], block["interpolation"], block["extension"]) == (1, "LINEAR", "REPEAT")
    view = document["bufferViews"][block["bufferView"]]
    start = view.get("byteOffset", 0)
    f0 = np.frombuffer(chunks[0][1][start : start + view["byteLength"]], "<f2").reshape(64, 64)
    closed = {ior: 2.0 * ((ior - 1.0) / (ior + 1.0)) ** 2 for ior in (1.2, 2.0)}
    assert np.all(f0[:, :32] == 0.0)  # (level 0)
    assert np.allclose(f0[:, 32:], closed[2.0], rtol=1e-3)
    level_tex.image = maps.halves_image(bpy, "ones", 1.0, 1.0)  # (the IOR's halves through level 1)
    document, chunks = glb.read(api.export_gltf(str(tmp_path / "ones.glb"), objects=[obj], scene=scene))
    block = document["materials"][0]["extras"]["PRT_lighting"]["f0_map"]
    view = document["bufferViews"][block["bufferView"]]
    start = view.get("byteOffset", 0)
    f0 = np.frombuffer(chunks[0][1][start : start + view["byteLength"]], "<f2").reshape(64, 64)
    assert np.allclose(f0[:, :32], closed[1.2], rtol=1e-3) and np.allclose(f0[:, 32:], closed[2.0], rtol=1e-3)
    texture = document["textures"][gltf_material["extensions"]["KHR_materials_specular"]["specularTexture"]["index"]]
    view = document["bufferViews"][document["images"][texture["source"]]["bufferView"]]
    start = view.get("byteOffset", 0)
    px = _png_pixels(bpy, chunks[0][1][start : start + view["byteLength"]], tmp_path)
    assert px.shape[2] < 4 or np.all(px[..., 3] == 1.0)
