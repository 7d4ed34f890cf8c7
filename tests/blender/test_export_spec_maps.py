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
