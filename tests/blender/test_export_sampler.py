"""The base colour map's glTF sampler follows the Image Texture node, so that three.js (the plugin
samples the loader's map as it is) filters and wraps it as the viewport does; Clip has no glTF
counterpart and is written as clamp to edge (docs/materials.md)."""

import pytest
from helpers import albedo_scenes
from helpers.gltf import _read_glb

from prt_addon import api

NEAREST, LINEAR, NEAREST_MIPMAP_NEAREST, LINEAR_MIPMAP_LINEAR = 9728, 9729, 9984, 9987  # glTF 2.0's enums
REPEAT, CLAMP_TO_EDGE, MIRRORED_REPEAT = 10497, 33071, 33648


@pytest.mark.parametrize(
    ("interpolation", "extension", "filters", "wrap"),
    [
        ("Linear", "REPEAT", (LINEAR, LINEAR_MIPMAP_LINEAR), REPEAT),
        ("Closest", "EXTEND", (NEAREST, NEAREST_MIPMAP_NEAREST), CLAMP_TO_EDGE),
        ("Linear", "MIRROR", (LINEAR, LINEAR_MIPMAP_LINEAR), MIRRORED_REPEAT),
        ("Linear", "CLIP", (LINEAR, LINEAR_MIPMAP_LINEAR), CLAMP_TO_EDGE),
    ],
)
def test_the_map_sampler_follows_the_image_node(
    bpy_module, empty_scene, tmp_path, interpolation, extension, filters, wrap
):
    bpy, scene = bpy_module, empty_scene
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    obj = bpy.context.active_object
    material = albedo_scenes.image_material(
        bpy, "halves", bpy.data.images.load(albedo_scenes.halves_png(str(tmp_path)))
    )
    node = next(n for n in material.node_tree.nodes if n.bl_idname == "ShaderNodeTexImage")
    node.interpolation, node.extension = interpolation, extension
    obj.data.materials.append(material)
    scene.world = bpy.data.worlds.new("white")
    api.project_world(scene, 2)
    api.bake([obj], order=2, samples=16)
    document = _read_glb(api.export_gltf(str(tmp_path / "map.glb"), scene=scene))[0]
    (texture,) = document["textures"]
    base = document["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]
    assert document["textures"][base["index"]] is texture
    sampler = document["samplers"][texture["sampler"]] if "sampler" in texture else {}
    assert (sampler.get("magFilter", LINEAR), sampler.get("minFilter", LINEAR_MIPMAP_LINEAR)) == filters
    assert (sampler.get("wrapS", REPEAT), sampler.get("wrapT", REPEAT)) == (wrap, wrap)
