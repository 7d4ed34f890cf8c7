"""Texel bakes in the .glb: the lightmap UV map as a TEXCOORD, the transfer (and bounced transfer) as 8-bit PNG planes that decode to the bake's coefficients, the radiance error the encoding adds."""

import json
import os
import subprocess

import numpy as np
import pytest
from helpers.fixtures_web import TEXEL_RESOLUTION
from helpers.gltf import VALIDATE_JS, _read_glb
from helpers.meshes import white_world
from helpers.png import _decode_png

BUDGET = 0.005  # of the mean radiance (what quantisation may add against render_view, docs/export.md)


def _planes(document, binary, meta, textures=None, decode=None):
    """The decoded coefficients (res, res, 4 G) of a texel mesh's PNG planes (the direct ones, or
    `textures` and `decode` of a bounce channel), glTF frame, row 0 the top (v_glTF = 0), by
    docs/export.md's rule."""
    texel = meta["texel"]
    res, (tiles_x, _tiles_y) = texel["resolution"], texel["tiles"]
    textures = texel["textures"] if textures is None else textures
    decode = texel["decode"] if decode is None else decode
    planes = []
    for index in textures:
        view = document["bufferViews"][document["images"][document["textures"][index]["source"]]["bufferView"]]
        data = binary[view.get("byteOffset", 0) : view.get("byteOffset", 0) + view["byteLength"]]
        planes.append(_decode_png(data).astype(np.float64))
    q = np.zeros_like(planes[0])
    for plane in planes:
        q = q * 256.0 + plane
    q /= 256.0 ** len(planes) - 1
    groups = len(decode)
    out = np.empty((res, res, 4 * groups))
    for g, entry in enumerate(decode):
        row, col = divmod(g, tiles_x)
        tile = q[row * res : (row + 1) * res, col * res : (col + 1) * res]
        out[..., 4 * g : 4 * g + 4] = np.asarray(entry["offset"]) + np.asarray(entry["scale"]) * tile
    return out


def _radiance(coeffs, lighting):
    """max(0, L . t) per texel and channel (glTF frame both)."""
    n2 = min(len(lighting), coeffs.shape[-1])
    return np.maximum(np.einsum("...i,ic->...c", coeffs[..., :n2], np.asarray(lighting)[:n2]), 0.0)


def _in_gltf_frame(values, n2):
    """(res, res, 4 G) stored coefficients rotated into glTF's frame, rows flipped (row 0 the top)."""
    from prt_addon.blender.export import gltf

    out = values.astype(np.float64)
    out[..., :n2] = gltf.to_gltf_frame(out[..., :n2].reshape(-1, n2).T).T.reshape(out.shape[:2] + (n2,))
    return out[::-1]


def test_a_texel_bake_with_bounces_exports_its_bounce_planes(bpy_module, empty_scene, tmp_path):
    """A green floor and a grey wall baked per texel with a bounce (3 channels): the export no
    longer refuses it, and each channel's planes decode to its stored bounce tiles within half a
    quantisation step. (First in the module: it empties the scene the texel demo then builds.)"""
    from prt_addon import api
    from prt_addon.blender.export import glb
    from prt_addon.blender.scene import storage, texel_storage

    bpy = bpy_module
    objs = []
    for name, location, rotation in (("Floor", (0, 0, 0), (0, 0, 0)), ("Wall", (0, 2, 1), (np.pi / 2, 0, 0))):
        bpy.ops.mesh.primitive_plane_add(size=4.0, location=location, rotation=rotation)
        bpy.context.object.name = name
        objs.append(bpy.context.object)
    green = bpy.data.materials.new("PRT test green")
    green.use_nodes = True
    green.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.2, 0.7, 0.3, 1.0)
    objs[0].data.materials.append(green)
    white_world(bpy, empty_scene)
    api.project_world(order=3, split_lights=False)
    report = api.bake(objs, order=3, samples=32, target="TEXELS", uv_map="UVMap", resolution=16, bounces=1)
    assert report.bounce_channels == 3
    for transfer, bits in (("snorm16", 16), ("snorm8", 8)):
        path = api.export_gltf(str(tmp_path / f"{transfer}.glb"), objs, environment_size=0, transfer=transfer)
        document, _acc = _read_glb(path)
        binary = glb.read(path)[1][0][1]
        metas = {m["name"]: m["extras"]["PRT_lighting"] for m in document["meshes"]}
        # Open quads: each has a back image, which the export leaves out (docs/export.md): the
        # file's images are the direct and bounce planes alone.
        assert len(document["images"]) == len(objs) * (1 + 3) * bits // 8
        for obj in objs:
            bake, _ = storage.read_bake_record(obj.data)
            assert bake.back and bake.back_image is not None
            meta = metas[obj.data.name]
            assert meta["version"] == 3 and meta["bounce_channels"] == 3 and meta["bounces"] == 1
            texel = meta["texel"]
            assert len(texel["bounce_textures"]) == 3 and len(texel["bounce_decode"]) == 3
            stored = texel_storage.read_texel_bounce(bake, padded=True)
            n2 = bake.order**2
            for c, (textures, decode) in enumerate(zip(texel["bounce_textures"], texel["bounce_decode"])):
                assert len(textures) == bits // 8 and len(decode) == bake.count
                assert not set(textures) & set(texel["textures"])
                expected = _in_gltf_frame(stored[:, :, c], n2)
                decoded = _planes(document, binary, meta, textures, decode)
                steps = np.array([e["scale"] for e in decode]).ravel() / (2.0**bits - 1)
                assert np.all(np.abs(decoded - expected) <= 0.5 * steps + 1e-7)
                assert np.ptp(expected[..., 0]) > 0  # (the bounce varies over the map: not a constant)
            direct = _planes(document, binary, meta)
            want = _in_gltf_frame(texel_storage.read_texel_transfer(bake, padded=True), n2)
            steps = np.array([e["scale"] for e in texel["decode"]]).ravel() / (2.0**bits - 1)
            assert np.all(np.abs(direct - want) <= 0.5 * steps + 1e-7)  # (the direct planes as before)
        # The wall's bounce is the green floor's: its green channel is not its red one.
        wall = metas[objs[1].data.name]["texel"]["bounce_decode"]
        assert wall[0] != wall[1]


def test_a_texel_bake_exports_as_png_planes_and_its_uv_map(texel_demo_scene, tmp_path, capsys, validator_modules):
    from prt_addon import api
    from prt_addon.blender.export import gltf
    from prt_addon.blender.scene import storage, texel_storage

    scene = texel_demo_scene
    ground = scene.objects["Ground"]
    bake, _ = storage.read_bake_record(ground.data)
    stored = texel_storage.read_texel_transfer(bake, padded=True).astype(np.float64)
    n2 = bake.order**2
    expected = stored.copy()
    expected[..., :n2] = gltf.to_gltf_frame(stored[..., :n2].reshape(-1, n2).T).T.reshape(stored.shape[:2] + (n2,))
    expected = expected[::-1]  # row 0 the top: v_glTF = 1 - v = 0
    figures = {}
    for transfer, bits in (("snorm16", 16), ("snorm8", 8)):
        path = api.export_gltf(str(tmp_path / f"{transfer}.glb"), transfer=transfer)
        document, _acc = _read_glb(path)
        from prt_addon.blender.export import glb

        binary = glb.read(path)[1][0][1]
        meshes = {m["name"]: m for m in document["meshes"] if "PRT_lighting" in m.get("extras", {})}
        meta = meshes["Grid"]["extras"]["PRT_lighting"]
        assert meta["version"] == 3 and meta["domain"] == "TEXEL" and meta["attributes"] == []
        assert meta["transfer_encoding"] == f"unorm{bits}_png"
        assert meta["texel"]["texcoord"] == 1 and meta["texel"]["uv_map"] == "Lightmap"
        assert meta["texel"]["resolution"] == TEXEL_RESOLUTION and len(meta["texel"]["textures"]) == bits // 8
        assert meshes["Suzanne"]["extras"]["PRT_lighting"]["version"] == 2  # the vertex bake as before
        decoded = _planes(document, binary, meta)
        steps = np.array([e["scale"] for e in meta["texel"]["decode"]]).ravel() / (2.0**bits - 1)
        assert np.all(np.abs(decoded - expected) <= 0.5 * steps + 1e-7)  # within half a step
        lighting = document["scenes"][0]["extras"]["PRT_lighting"]["coefficients"]
        truth, got = _radiance(expected, lighting), _radiance(decoded, lighting)
        diff = np.abs(got - truth).max(axis=-1) / truth.mean()
        figures[transfer] = (diff.mean(), np.percentile(diff, 99), diff.max(), os.path.getsize(path))
        if transfer == "snorm16":
            assert diff.max() < BUDGET / 10
            _check_texcoord(document, path, ground)
            env = dict(os.environ, NODE_PATH=validator_modules)
            out = subprocess.run(
                ["node", "-e", VALIDATE_JS, path], capture_output=True, text=True, env=env, timeout=120
            )
            assert out.returncode == 0, out.stderr
            issues = json.loads(out.stdout)
            assert issues["numErrors"] == 0, [m for m in issues["messages"] if m["severity"] == 0]
    with capsys.disabled():
        for name, (mean, p99, top, size) in figures.items():
            print(
                f"\ntexel export {name}: radiance error mean {100 * mean:.4f} % p99 {100 * p99:.4f} % max {100 * top:.4f} %, {size} bytes"
            )


def _check_texcoord(document, path, ground):
    """The primitive's TEXCOORD_1 is the Lightmap UV map as (u, 1 - v), vertex by vertex."""
    _doc, accessor = _read_glb(path)
    mesh = next(m for m in document["meshes"] if m["name"] == "Grid")
    uv = ground.data.uv_layers["Lightmap"].uv
    values = np.empty(len(uv) * 2, np.float32)
    uv.foreach_get("vector", values)
    values = values.reshape(-1, 2)
    positions = np.empty(len(ground.data.vertices) * 3, np.float32)
    ground.data.vertices.foreach_get("co", positions)
    corners = np.empty(len(ground.data.loops), np.int32)
    ground.data.loops.foreach_get("vertex_index", corners)
    blender = {
        (tuple(np.round(positions.reshape(-1, 3)[v], 4)), (round(float(u), 4), round(1.0 - float(w), 4)))
        for v, (u, w) in zip(corners, values)
    }
    for prim in mesh["primitives"]:
        pos = accessor(prim["attributes"]["POSITION"])
        tex = accessor(prim["attributes"]["TEXCOORD_1"])
        blender_pos = np.c_[pos[:, 0], -pos[:, 2], pos[:, 1]]  # glTF (x, y, z) = Blender (x, z, -y)
        got = {
            (tuple(np.round(p, 4)), (round(float(t[0]), 4), round(float(t[1]), 4))) for p, t in zip(blender_pos, tex)
        }
        assert got <= blender and len(got) > 100


@pytest.mark.parametrize("transfer", ["float32"])
def test_float32_asked_of_a_texel_bake_writes_16_bit(texel_demo_scene, tmp_path, transfer):
    """PNG planes hold no floats: a texel bake goes in 16 bits whatever encoding the vertices get."""
    from prt_addon import api

    document, _ = _read_glb(api.export_gltf(str(tmp_path / "f.glb"), transfer=transfer))
    metas = {
        m["name"]: m["extras"]["PRT_lighting"] for m in document["meshes"] if "PRT_lighting" in m.get("extras", {})
    }
    assert metas["Grid"]["transfer_encoding"] == "unorm16_png"
    assert metas["Suzanne"]["transfer_encoding"] == "float32" and metas["Suzanne"]["version"] == 1
