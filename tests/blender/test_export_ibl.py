"""EXT_lights_image_based in the export: complete JSON, embedded PNGs, the validator, options, cost on forest.exr."""

import json
import os
import subprocess

import numpy as np
import pytest
from helpers.gltf import VALIDATE_JS
from helpers.png import _decode_png
from helpers.sampling import random_directions
from helpers.worlds import bundled_hdri_path


@pytest.fixture
def forest_scene(empty_scene, bpy_module):
    """forest.exr behind a Mapping rotation, the sun split off, a baked ico sphere."""
    from prt_addon import api

    bpy = bpy_module
    world = bpy.data.worlds.new("Forest")
    if world.node_tree is None:
        world.use_nodes = True
    empty_scene.world = world
    tree = world.node_tree
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(bundled_hdri_path("forest"))
    tree.links.new(env.outputs["Color"], tree.nodes["Background"].inputs["Color"])
    coords, mapping = tree.nodes.new("ShaderNodeTexCoord"), tree.nodes.new("ShaderNodeMapping")
    tree.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    tree.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, 0.8)
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=1)
    api.project_world(order=4, split_lights=True)
    api.bake([bpy.context.object], order=3, samples=16)
    return empty_scene


def test_extension_json_is_complete(forest_scene, tmp_path):
    from prt_addon.blender.export import glb, gltf, ibl
    from prt_addon.core.ibl import prefilter
    from prt_addon.core.sh import basis as sh

    path = str(tmp_path / "forest.glb")
    gltf.export_gltf(path)
    document, chunks = glb.read(path)
    assert ibl.EXTENSION in document["extensionsUsed"]
    assert ibl.EXTENSION not in document.get("extensionsRequired", [])
    lights = document["extensions"][ibl.EXTENSION]["lights"]
    assert len(lights) == 1
    light = lights[0]
    assert set(light) >= {"intensity", "rotation", "irradianceCoefficients", "specularImageSize", "specularImages"}
    assert light["intensity"] == 1.0
    assert light["rotation"] == [0.0, 0.0, 0.0, 1.0]
    assert light["specularImageSize"] == ibl.DEFAULT_SIZE == 128
    assert np.array(light["irradianceCoefficients"]).shape == (9, 3)
    for gltf_scene in document["scenes"]:
        assert gltf_scene["extensions"][ibl.EXTENSION] == {"light": 0}
    specular = light["specularImages"]
    assert len(specular) == 8
    assert all(len(row) == 6 for row in specular)
    binary = chunks[0][1]
    assert document["buffers"][0]["byteLength"] <= len(binary) < document["buffers"][0]["byteLength"] + 4
    for k, row in enumerate(specular):
        for f, index in enumerate(row):
            image = document["images"][index]
            assert image["mimeType"] == "image/png"
            view = document["bufferViews"][image["bufferView"]]
            data = binary[view["byteOffset"] : view["byteOffset"] + view["byteLength"]]
            rgba = _decode_png(data)
            assert rgba.shape == (128 >> k, 128 >> k, 4), (k, f)
            assert rgba[..., 3].min() >= 1  # RGBD's D is never 0
    # The irradiance is of the full world: the PRT sky plus the split lights.
    lighting = document["scenes"][0]["extras"]["PRT_lighting"]
    assert lighting["lights"], "forest.exr's sun was expected to be split off"
    full = np.array(lighting["coefficients"]) + np.array(lighting["lights_coefficients"])
    g = random_directions(50, 9)
    ours = sh.sh_basis(g, 3) @ (full[:9] * ibl.COSINE_BANDS[:, None])
    assert np.allclose(ibl.babylon_irradiance(light["irradianceCoefficients"], g), ours, rtol=1e-12, atol=1e-9)
    assert light["extras"]["PRT_lighting"]["roughness"] == pytest.approx(np.sqrt(prefilter.babylon_alphas(128)))
    # The file without the environment has no trace of it.
    plain = str(tmp_path / "plain.glb")
    gltf.export_gltf(plain, environment_size=0)
    document_plain, _ = glb.read(plain)
    assert "extensions" not in document_plain
    assert ibl.EXTENSION not in document_plain.get("extensionsUsed", [])


def test_irradiance_signs_by_hand():
    """Babylon's basis (Condon-Shortley) in its frame (x negated): each of our 9 basis functions
    in glTF's frame is +-1 times Babylon's at the mirrored direction, with BABYLON_SIGNS."""
    from prt_addon.blender.export import ibl
    from prt_addon.core.sh import basis as sh

    g = random_directions(20, 4)
    for i in range(9):
        coeffs = np.zeros((9, 3))
        coeffs[i] = 1.0
        bab = ibl.irradiance_coefficients(coeffs) / ibl.COSINE_BANDS[i]
        x, y, z = (g * [-1.0, 1.0, 1.0]).T  # Babylon's direction of glTF's g
        c1, c2 = np.sqrt(3 / (4 * np.pi)), np.sqrt(15 / (4 * np.pi))
        babylon_basis = np.stack(  # Babylon's SH3ylmBasisConstants times its trigonometric terms
            [
                np.full_like(x, np.sqrt(1 / (4 * np.pi))),
                -c1 * y,
                c1 * z,
                -c1 * x,
                c2 * x * y,
                -c2 * y * z,
                np.sqrt(5 / (16 * np.pi)) * (3 * z * z - 1),
                -c2 * x * z,
                np.sqrt(15 / (16 * np.pi)) * (x * x - y * y),
            ],
            axis=1,
        )
        assert np.allclose(babylon_basis @ bab[:, 0], sh.sh_basis(g, 3)[:, i]), i


def test_validator_accepts_the_environment(forest_scene, tmp_path, validator_modules):
    from prt_addon import api

    path = api.export_gltf(str(tmp_path / "v.glb"))
    env = dict(os.environ, NODE_PATH=validator_modules)
    out = subprocess.run(["node", "-e", VALIDATE_JS, path], capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    issues = json.loads(out.stdout)
    assert issues["numErrors"] == 0, [m for m in issues["messages"] if m["severity"] == 0]


def test_bad_environment_size_is_refused(forest_scene, tmp_path):
    from prt_addon.blender.export import gltf

    for size in (96, -4, 2.5):
        with pytest.raises(ValueError, match="power of two"):
            gltf.export_gltf(str(tmp_path / "bad.glb"), environment_size=size)
    with pytest.raises(ValueError, match="at most 256"):
        gltf.export_gltf(str(tmp_path / "bad.glb"), environment_size=512)
    assert list(tmp_path.iterdir()) == []


def test_operator_writes_the_chosen_environment_size(forest_scene, bpy_module, tmp_path):
    from prt_addon.blender.export import glb

    for choice, mips in (("0", 0), ("64", 7)):
        path = str(tmp_path / f"op{choice}.glb")
        assert bpy_module.ops.prt.export_gltf(filepath=path, environment_size=choice) == {"FINISHED"}
        document, _chunks = glb.read(path)
        lights = document.get("extensions", {}).get("EXT_lights_image_based", {}).get("lights", [])
        assert len(lights) == (1 if mips else 0)
        if mips:
            assert lights[0]["specularImageSize"] == 64
            assert len(lights[0]["specularImages"]) == mips


def test_constant_world_environment(empty_scene, bpy_module, tmp_path):
    """A plain colour world: every texel of every mip is the colour times the strength."""
    from prt_addon import api
    from prt_addon.blender.export import glb, gltf, ibl
    from prt_addon.core.ibl import rgbd_png

    bpy = bpy_module
    world = bpy.data.worlds.new("Grey")
    if world.node_tree is None:
        world.use_nodes = True
    empty_scene.world = world
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.5, 0.6, 0.7, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 2.0
    bpy.ops.mesh.primitive_cube_add()
    api.project_world(order=3)
    api.bake([bpy.context.object], order=3, samples=16)
    path = str(tmp_path / "grey.glb")
    gltf.export_gltf(path, environment_size=16)
    document, chunks = glb.read(path)
    light = document["extensions"][ibl.EXTENSION]["lights"][0]
    for row in light["specularImages"]:
        for index in row:
            view = document["bufferViews"][document["images"][index]["bufferView"]]
            rgba = _decode_png(chunks[0][1][view["byteOffset"] : view["byteOffset"] + view["byteLength"]])
            assert np.allclose(rgbd_png.rgbd_decode(rgba), [1.0, 1.2, 1.4], rtol=0.01)
    e = np.array(light["irradianceCoefficients"])
    assert np.allclose(e[0] / np.sqrt(4 * np.pi), np.pi * np.array([1.0, 1.2, 1.4]))  # E = pi L
    assert np.allclose(e[1:], 0.0, atol=1e-9)
