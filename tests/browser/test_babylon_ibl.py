"""EXT_lights_image_based against its reference loader: the exported .glb loaded by Babylon.js in headless Chromium."""

import json
import os
import shutil
import subprocess

import numpy as np
import pytest
from helpers.paths import ROOT
from helpers.web import _tool

SIZE = 64  # the test's cube map (mip 0 face size)
EULER = (0.4, -0.3, 1.1)  # the World's Mapping rotation
STRENGTH = 1.25

# Tolerances (measured values in docs/export.md, "Tested against Babylon.js").
IRRADIANCE_TOLERANCE = 1e-3  # of the mean irradiance over the test directions
MIP0_TOLERANCE = 0.03  # Babylon's bilinear mip 0 against the analytic world, of max(value, 0.1)
MIPS_TOLERANCE = 0.01  # Babylon's texels of mips 1.. against the exported (RGBD-decoded) values
MIRROR_TOLERANCE = 0.1  # the metal sphere's centre pixel (8 bit, linear) against the world
ROUGHNESS = 0.25  # the rough sphere's (Babylon picks lod log2(64 alpha) = 2.01: mip 2)
ROUGH_TOLERANCE = 0.05  # its centre pixel facing the spot against Babylon's model of our mip

BLOBS = [  # (direction in the image's frame, colour, width in 1 - cos): an asymmetric world
    (np.array([0.5, 0.7, 0.5]), np.array([0.45, 0.36, 0.27]), 0.03),
    (np.array([-0.6, 0.2, -0.3]), np.array([0.06, 0.3, 0.09]), 0.05),
]


def world_function(d):
    """Radiance (..., 3) of the test image at image-frame unit directions d (..., 3)."""
    d = np.asarray(d, dtype=np.float64)
    value = (
        np.array([0.2, 0.22, 0.25]) + 0.1 * d[..., :1] + 0.05 * d[..., 2:3] + np.array([0.04, 0.0, 0.0]) * d[..., 1:2]
    )
    for axis, colour, width in BLOBS:
        axis = axis / np.linalg.norm(axis)
        value = value + colour * np.exp((d @ axis - 1.0) / width)[..., None]
    return value


@pytest.fixture(scope="module")
def tools():
    for tool in ("node", "npm"):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} is needed for the Babylon.js test (install Node.js)")
    return {"chromium": _tool("setup_chromium.sh"), "modules": _tool("setup_node.sh")}


@pytest.fixture(scope="module")
def exported(bpy_module, addon, tmp_path_factory):
    """A scene lit by the test image (Mapping rotation, strength), a baked ico sphere, exported."""
    from prt_addon import api
    from prt_addon.blender.export import gltf
    from prt_addon.blender.world import nodes
    from prt_addon.core.sh import projection

    bpy = bpy_module
    bpy.ops.wm.read_factory_settings(use_empty=True)
    height = 256
    image = bpy.data.images.new("PRT test sky", 2 * height, height, float_buffer=True)
    rgb = world_function(projection.pixel_directions(height, 2 * height))
    rgba = np.concatenate([rgb, np.ones((height, 2 * height, 1))], axis=2).astype(np.float32)
    image.pixels.foreach_set(rgba.ravel())
    world = bpy.data.worlds.new("PRT test world")
    if world.node_tree is None:
        world.use_nodes = True
    bpy.context.scene.world = world
    tree = world.node_tree
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = image
    tree.links.new(env.outputs["Color"], tree.nodes["Background"].inputs["Color"])
    tree.nodes["Background"].inputs["Strength"].default_value = STRENGTH
    coords, mapping = tree.nodes.new("ShaderNodeTexCoord"), tree.nodes.new("ShaderNodeMapping")
    tree.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    tree.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    mapping.inputs["Rotation"].default_value = EULER
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=1, location=(0.0, 0.0, 0.0))
    api.project_world(order=4)
    api.bake([bpy.context.object], order=3, samples=16)
    path = str(tmp_path_factory.mktemp("babylon") / "ibl.glb")
    gltf.export_gltf(path, environment_size=SIZE)
    q = nodes.live_sh_rotation(world)

    def radiance(g):  # the world at glTF directions, from the analytic image (not the cube)
        w = np.asarray(g) @ gltf.BLENDER_TO_GLTF  # C^T g, row-wise
        return STRENGTH * world_function(w @ q)  # image(Q^T w), row-wise

    return {"path": path, "radiance": radiance, "mips": api_mips(bpy.context.scene)}


def api_mips(scene):
    from prt_addon.blender.export import ibl
    from prt_addon.core.ibl import rgbd_png

    return [rgbd_png.rgbd_decode(rgbd_png.rgbd_encode(m)) for m in ibl.specular_mips(scene, SIZE)]


def _run(tools, job, tmp_path):
    job = dict(job, chromium=tools["chromium"], work=str(tmp_path))
    path = tmp_path / "job.json"
    path.write_text(json.dumps(job))
    run = subprocess.run(
        ["node", os.path.join(ROOT, "web", "tools", "babylon_ibl.mjs"), str(path)],
        capture_output=True,
        text=True,
        timeout=900,
        env=dict(os.environ, PRT_NODE_MODULES=tools["modules"]),
    )
    assert run.returncode == 0, run.stderr[-3000:]
    summary = json.loads(run.stdout.strip().splitlines()[-1])
    assert summary["requests"] == [], summary["requests"]
    assert not [m for m in summary["console"] if m.startswith("pageerror")], summary["console"]
    return summary


def _babylon_directions(texture, g):
    """glTF directions (k, 3) in Babylon's world through the loader's root node matrix."""
    root = np.array(texture["root"]).reshape(4, 4)[:3, :3]  # row-major: b = g @ root
    b = np.asarray(g) @ root
    return b / np.linalg.norm(b, axis=1, keepdims=True)


def _shader_irradiance(texture, g):
    """pi times Babylon's PBR shader SH sum (its vSphericalL.. uniforms = preScaledHarmonics)."""
    x, y, z = _babylon_directions(texture, g).T
    h = np.array(texture["harmonics"])
    terms = np.stack([np.ones_like(x), y, z, x, y * x, y * z, 3 * z * z - 1, z * x, x * x - y * y], axis=1)
    return np.pi * terms @ h


def _texel_dirs_gltf(size, rng, count):
    """`count` random texel centres of a mip of `size`: (face, row, col) and their glTF directions."""
    from prt_addon.blender.export import ibl
    from prt_addon.core.ibl import prefilter

    dirs = prefilter.face_directions(size).reshape(-1, 3)
    pick = rng.choice(dirs.shape[0], size=min(count, dirs.shape[0]), replace=False)
    return pick, dirs[pick] @ ibl.BABYLON_FROM_GLTF.T


def test_babylon_reads_our_environment(exported, tools, tmp_path, capsys):
    """Babylon's environment texture: its irradiance SH is our E(n), its mip 0 the world in the
    right directions (and not the mirrored ones), its other mips our prefiltered texels, and a
    mirror sphere reflects the bright spot where the world has it."""
    from prt_addon.blender.export import glb, ibl
    from prt_addon.core.sh import basis as sh

    rng = np.random.default_rng(5)
    document, _chunks = glb.read(exported["path"])
    lighting = document["scenes"][0]["extras"]["PRT_lighting"]
    radiance_sh = np.array(lighting["coefficients"]) + np.array(lighting["lights_coefficients"])
    g = rng.normal(size=(200, 3))
    g /= np.linalg.norm(g, axis=1, keepdims=True)
    lods = list(range(1, SIZE.bit_length()))
    texels = {k: _texel_dirs_gltf(SIZE >> k, rng, 300) for k in lods}
    axis, _colour, _width = BLOBS[0]
    import bpy

    from prt_addon.blender.export.gltf import BLENDER_TO_GLTF
    from prt_addon.blender.world import nodes

    q = nodes.live_sh_rotation(bpy.context.scene.world)
    spot = BLENDER_TO_GLTF @ q @ (axis / np.linalg.norm(axis))  # the blob in glTF's world
    mirrored = spot * np.array([-1.0, 1.0, 1.0])
    other = np.cross(spot, [0.0, 1.0, 0.0])
    cameras = [spot, mirrored, spot * np.array([1.0, -1.0, 1.0]), other / np.linalg.norm(other)]
    job = {
        "glb": exported["path"],
        "samples": [{"dirs": g.tolist(), "lod": 0}, {"dirs": (g * [-1.0, 1.0, 1.0]).tolist(), "lod": 0}]
        + [{"dirs": texels[k][1].tolist(), "lod": k} for k in lods],
        "mirrors": [
            {"dirs": np.array(cameras).tolist(), "roughness": 0.0},
            {"dirs": np.array(cameras).tolist(), "roughness": ROUGHNESS},
        ],
    }
    summary = _run(tools, job, tmp_path)
    texture = summary["texture"]
    assert texture["size"] == SIZE
    assert texture["level"] == 1.0
    assert not texture["useRightHandedSystem"]
    assert texture["lodGenerationScale"] == pytest.approx(1.0)
    assert texture["lodGenerationOffset"] == 0.0
    assert np.allclose(np.array(texture["reflectionMatrix"]).reshape(4, 4), np.eye(4))
    figures = {}

    # (a) irradiance: Babylon's shader SH against E = A_l L_lm of the file's PRT lighting.
    ours = sh.sh_basis(g, 3) @ (radiance_sh[:9] * ibl.COSINE_BANDS[:, None])
    theirs = _shader_irradiance(texture, g)
    figures["irradiance"] = float(np.abs(theirs - ours).max() / ours.mean())
    assert figures["irradiance"] < IRRADIANCE_TOLERANCE, figures

    # (b) mip 0 against the analytic world in the same glTF directions, and not the mirrored ones.
    want = exported["radiance"](g)
    scale = np.maximum(want, 0.1)
    got, got_mirrored = np.array(summary["samples"][0]), np.array(summary["samples"][1])
    figures["mip0"] = float((np.abs(got - want) / scale).max())
    figures["mip0_mirrored_frame"] = float((np.abs(got_mirrored - want) / scale).max())
    assert figures["mip0"] < MIP0_TOLERANCE, figures
    assert figures["mip0_mirrored_frame"] > 10 * MIP0_TOLERANCE, figures

    # (c) every other mip: Babylon's texel at our texel's direction is the value we wrote there.
    worst = 0.0
    for k, result in zip(lods, summary["samples"][2:], strict=True):
        pick, _dirs = texels[k]
        ref = exported["mips"][k].reshape(-1, 3)[pick]
        worst = max(worst, float((np.abs(np.array(result) - ref) / np.maximum(ref, 0.05)).max()))
    figures["mips"] = worst
    assert worst < MIPS_TOLERANCE, figures

    # (d) a metal mirror sphere rendered by Babylon's PBR shader reflects the spot where it is.
    # Babylon's default scene writes linear values (its image processing is off by default).
    pixels = np.array(summary["mirrors"][0])[:, :3] / 255.0
    expected = exported["radiance"](np.array(cameras))
    figures["mirror"] = float((np.abs(pixels - expected) / np.maximum(expected, 0.1)).max())
    figures["mirror_pixels"] = pixels.round(3).tolist()
    figures["mirror_expected"] = expected.round(3).tolist()
    with capsys.disabled():
        print("Babylon.js figures:", json.dumps(figures))
    assert pixels[0].sum() > 2.0 * pixels[1].sum(), figures  # the spot, not its mirror image
    assert figures["mirror"] < MIRROR_TOLERANCE, figures

    # (e) a rough metal sphere: Babylon mixes the radiance with the irradiance by alpha (its
    # MIX_IBL_RADIANCE_WITH_IRRADIANCE, on by default), alpha = roughness^2 + 0.0005 (its
    # MINIMUMVARIANCE): (1 - alpha) G + alpha E / pi, G the GGX integral of the analytic world in
    # the reflected direction by an independent quadrature. Checked where the spot is, where the
    # mip's data dominates; the dim directions come out 0.02-0.04 brighter than this model.
    rough = np.array(summary["mirrors"][1])[:, :3] / 255.0
    from prt_addon.core.sh import directions

    points = directions.fibonacci_directions(200_000)
    values = exported["radiance"](points)
    alpha = ROUGHNESS**2 + 0.0005
    c = np.array(cameras) @ points.T
    w = np.maximum(c, 0) / (alpha**2 + (1 - c) * (1 - alpha**2) / 2) ** 2
    ggx = (w @ values) / w.sum(axis=1, keepdims=True)
    expected = (1 - alpha) * ggx + alpha * _shader_irradiance(texture, np.array(cameras)) / np.pi
    error = np.abs(rough - expected) / np.maximum(expected, 0.1)
    figures["rough_spot"] = float(error[0].max())
    figures["rough_others"] = float(error[1:].max())
    figures["rough_pixels"] = rough.round(3).tolist()
    figures["rough_expected"] = expected.round(3).tolist()
    with capsys.disabled():
        print("Babylon.js rough sphere:", json.dumps({k: v for k, v in figures.items() if k.startswith("rough")}))
    assert figures["rough_spot"] < ROUGH_TOLERANCE, figures
    assert rough[0].sum() > 2.0 * rough[1].sum(), figures
