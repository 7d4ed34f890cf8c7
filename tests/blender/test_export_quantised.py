"""The quantised transfer of the export (blender/export/quantise.py): error bound, the BIN chunk rewritten, sizes, validator."""

import json
import os
import subprocess

import numpy as np
import pytest
from helpers.gltf import VALIDATE_JS, _read_glb, _transfer

from prt_addon.blender.export import quantise


@pytest.mark.parametrize("encoding", ["snorm16", "snorm8"])
def test_encoding_is_within_half_a_step(encoding):
    """Decoded values are within half a step (scale / K) of the input per component; a constant
    component (scale 0) and each component's extremes come back exactly."""
    _component, k, _dtype = quantise.ENCODINGS[encoding]
    rng = np.random.default_rng(3)
    values = rng.normal(size=(5000, 4)) * [1.0, 0.01, 30.0, 0.0] + [0.0, 0.5, -2.0, 0.25]
    q, offset, scale = quantise.encode(values, k)
    assert q.min() >= -k and q.max() <= k
    got = quantise.decode(q, offset, scale, k)
    err = np.abs(got - values)
    assert (err <= 0.5 * scale / k * (1 + 1e-9) + 1e-15).all()
    assert np.array_equal(got[:, 3], values[:, 3]) and scale[3] == 0
    for c in range(3):
        for i in (values[:, c].argmin(), values[:, c].argmax()):
            assert got[i, c] == pytest.approx(values[i, c], rel=1e-12, abs=1e-15)
    # The step is the claim: a coarser encoding really is further off.
    assert err[:, 2].max() > 0.25 * scale[2] / k


def _document(rows, stride):
    """A one-mesh glTF: positions (own view), the transfer in a view of `stride` bytes per row, an image."""
    positions = np.arange(len(rows) * 3, dtype=np.float32).reshape(-1, 3)
    padded = np.zeros((len(rows), stride // 4), np.float32)
    padded[:, :4] = rows
    image = bytes(range(37))
    parts = [positions.tobytes(), b"\0" * (-positions.nbytes % 8), padded.tobytes(), image]
    binary = b"".join(parts)
    t_start = positions.nbytes + (-positions.nbytes % 8)
    document = {
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": len(binary)}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": positions.nbytes, "target": 34962},
            {"buffer": 0, "byteOffset": t_start, "byteLength": padded.nbytes, "byteStride": stride, "target": 34962},
            {"buffer": 0, "byteOffset": t_start + padded.nbytes, "byteLength": len(image)},
        ],
        "accessors": [
            {
                "bufferView": 0,
                "componentType": 5126,
                "count": len(rows),
                "type": "VEC3",
                "min": [0] * 3,
                "max": [1] * 3,
            },
            {
                "bufferView": 1,
                "componentType": 5126,
                "count": len(rows),
                "type": "VEC4",
                "min": [0] * 4,
                "max": [1] * 4,
            },
        ],
        "images": [{"bufferView": 2, "mimeType": "image/png"}],
        "meshes": [
            {
                "primitives": [{"attributes": {"POSITION": 0, "_PRT_T0": 1}}],
                "extras": {"PRT_lighting": {"version": 1, "order": 2, "attributes": ["_PRT_T0"]}},
            }
        ],
    }
    return document, [(0x004E4942, binary)], positions.tobytes(), image


@pytest.mark.parametrize("stride", [16, 32])
def test_quantise_rewrites_only_the_transfer(stride):
    """The transfer accessor becomes normalised SHORT in a view of its own; the other views' bytes
    are kept and re-pointed (an image included), the float bytes are gone, the extras say how to
    decode (version 2)."""
    rng = np.random.default_rng(5)
    rows = rng.normal(size=(50, 4)).astype(np.float32)
    document, chunks, positions, image = _document(rows, stride)
    size = len(chunks[0][1])
    chunks = quantise.quantise(document, chunks, "snorm16")
    binary = chunks[0][1]
    assert document["buffers"][0]["byteLength"] == len(binary)
    assert size - len(binary) >= rows.shape[0] * (stride - 8) - 16  # float rows out, 8-byte rows in
    views = document["bufferViews"]
    p = views[document["accessors"][0]["bufferView"]]
    assert binary[p["byteOffset"] : p["byteOffset"] + p["byteLength"]] == positions
    im = views[document["images"][0]["bufferView"]]
    assert binary[im["byteOffset"] : im["byteOffset"] + im["byteLength"]] == image
    acc = document["accessors"][1]
    assert (acc["componentType"], acc["normalized"], "min" in acc) == (5122, True, False)
    view = views[acc["bufferView"]]
    assert view["byteOffset"] % 8 == 0 and "byteStride" not in view
    q = np.frombuffer(binary, np.int16, rows.size, view["byteOffset"]).reshape(-1, 4)
    meta = document["meshes"][0]["extras"]["PRT_lighting"]
    assert (meta["version"], meta["transfer_encoding"], len(meta["decode"])) == (2, "snorm16", 1)
    got = quantise.decode(q, meta["decode"][0]["offset"], meta["decode"][0]["scale"], 32767)
    assert np.abs(got - rows).max() <= 0.5 * max(meta["decode"][0]["scale"]) / 32767 * 1.0001


def test_float32_leaves_the_file_alone():
    document, chunks, _positions, _image = _document(np.ones((4, 4), np.float32), 16)
    before = json.dumps(document)
    assert quantise.quantise(document, chunks, "float32") is chunks and json.dumps(document) == before
    with pytest.raises(ValueError, match="unknown transfer encoding"):
        quantise.quantise(document, chunks, "half")


def test_quantised_files_are_smaller_and_valid(baked, tmp_path, validator_modules):
    """Per encoding, the binary chunk is smaller than float32's by the transfer's bytes (to the
    views' padding), the Khronos validator finds no error, and a bad encoding is refused before writing."""
    from prt_addon.blender.export import glb, gltf

    sizes, values = {}, {}
    for encoding in ("float32", "snorm16", "snorm8"):
        path = gltf.export_gltf(str(tmp_path / f"{encoding}.glb"), transfer=encoding)
        document, accessor = _read_glb(path)
        sizes[encoding] = len(glb.read(path)[1][0][1])  # the BIN chunk (the JSON grows by the decode table)
        transfer = [
            (mesh, prim)
            for mesh in document["meshes"]
            if "PRT_lighting" in mesh.get("extras", {})
            for prim in mesh["primitives"]
        ]
        values[encoding] = np.concatenate(
            [_transfer(document, accessor, mesh, prim).ravel() for mesh, prim in transfer]
        )
        components = sum(
            document["accessors"][prim["attributes"][name]]["count"] * 4
            for mesh, prim in transfer
            for name in mesh["extras"]["PRT_lighting"]["attributes"]
        )
        out = subprocess.run(
            ["node", "-e", VALIDATE_JS, path],
            capture_output=True,
            text=True,
            env=dict(os.environ, NODE_PATH=validator_modules),
            timeout=120,
        )
        assert out.returncode == 0, out.stderr
        issues = json.loads(out.stdout)
        assert issues["numErrors"] == 0, [m for m in issues["messages"] if m["severity"] == 0]
    views = len(transfer) * 4  # at most 8 bytes of padding per rewritten view
    assert abs((sizes["float32"] - sizes["snorm16"]) - 2 * components) <= 8 * views
    assert abs((sizes["float32"] - sizes["snorm8"]) - 3 * components) <= 8 * views
    scale = np.abs(values["float32"]).max()
    assert np.abs(values["snorm16"] - values["float32"]).max() < 1e-4 * scale
    assert np.abs(values["snorm8"] - values["float32"]).max() < 1e-2 * scale
    with pytest.raises(ValueError, match="unknown transfer encoding"):
        gltf.export_gltf(str(tmp_path / "bad.glb"), transfer="half")
    assert not (tmp_path / "bad.glb").exists()
