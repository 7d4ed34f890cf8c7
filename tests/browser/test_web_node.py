"""The plugin's maths in node (no browser): transfer decoding against the export's quantise, the format checks, rotation inputs."""

import json
import os
import shutil
import subprocess

import numpy as np
import pytest
from helpers.paths import ROOT

from prt_addon.blender.export import quantise
from prt_addon.core.sh import rotation

SRC = os.path.join(ROOT, "web", "src")

SCRIPT = """
import * as THREE from 'three';
import fs from 'node:fs';
import { geometryTransferSource, packedTransferSource } from %(src)s/transfer_source.js;
import { readLighting, readTransfer } from %(src)s/format.js;
import { rotationRows } from %(src)s/rotation_input.js;
const job = JSON.parse(fs.readFileSync(0, 'utf8'));
const out = { decoded: [], checks: [], rotations: [], packed: [] };
for (const c of job.packed || []) {
  // The shader's arithmetic in JS: r_c = constant_c + sum_k dot(unpacked vec4 k of block blocks[c], rows_k).
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(c.vertices * 3), 3));
  c.attributes.forEach((a, k) => geometry.setAttribute(`_prt_t${k}`, new THREE.BufferAttribute(Int16Array.from(a), 4, true)));
  const spec = readTransfer(c.meta, geometry);
  const source = packedTransferSource(geometry, spec);
  const { rows, constant } = source.lightFor(c.light, c.blocks);
  const radiance = [];
  for (let v = 0; v < c.vertices; v++) {
    const r = constant.slice();
    for (let ch = 0; ch < 3; ch++) {
      for (let k = 0; k < spec.count; k++) {
        const i = c.blocks[ch] * spec.count + k;
        const packed = geometry.attributes[`prtPacked${i >> 1}`].array;
        for (let j = 0; j < 4; j++) {
          const word = packed[4 * v + j];
          const q = i % 2 ? word >> 16 : (word << 16) >> 16;
          r[ch] += q * (rows[4 * k + j] ? rows[4 * k + j][ch] : 0);
        }
      }
    }
    radiance.push(r);
  }
  out.packed.push({ radiance, kind: source.kind, slots: Object.keys(geometry.attributes).filter((n) => n.startsWith('prtPacked')).length });
}
for (const c of job.decode) {
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(c.vertices * 3), 3));
  c.attributes.forEach((a, k) => {
    const Type = { snorm16: Int16Array, snorm8: Int8Array, float32: Float32Array }[c.meta.transfer_encoding];
    const array = Type.from(a);
    const attr = c.interleaved
      ? new THREE.InterleavedBufferAttribute(new THREE.InterleavedBuffer(array, 4), 4, 0, Type !== Float32Array)
      : new THREE.BufferAttribute(array, 4, Type !== Float32Array);
    geometry.setAttribute(`_prt_t${k}`, attr);
  });
  const spec = readTransfer(c.meta, geometry);
  const source = geometryTransferSource(geometry, spec, 64);
  const tex = source.uniforms.prtTransferTx.value;
  out.decoded.push({ data: Array.from(tex.image.data), width: tex.image.width, perRow: source.uniforms.prtPerRow.value });
}
for (const c of job.checks) {
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(6), 3));
  for (const name of c.attributes || []) geometry.setAttribute(name, new THREE.BufferAttribute(new Float32Array(8), 4));
  for (const name of c.uvs || []) geometry.setAttribute(name, new THREE.BufferAttribute(new Float32Array(4), 2));
  try {
    if (c.kind === 'lighting') readLighting(c.meta);
    const spec = c.kind === 'lighting' ? { warnings: [] } : readTransfer(c.meta, geometry, c.json || {});
    if (spec.warnings.length) out.checks.push(`warning: ${spec.warnings.join('; ')}`);
    else out.checks.push(spec.contact ? `ok, contact ${spec.contact}` : 'ok');
  } catch (error) {
    out.checks.push(`${error.name === 'Error' && error.constructor.name === 'FormatError' ? 'FormatError' : error.constructor.name}: ${error.message}`);
  }
}
for (const r of job.rotations) {
  const input = r.kind === 'euler' ? new THREE.Euler(...r.values, 'XYZ')
    : r.kind === 'quaternion' ? new THREE.Quaternion(...r.values)
    : r.kind === 'matrix3' ? new THREE.Matrix3().set(...r.values)
    : new THREE.Matrix4().set(...r.values);
  out.rotations.push(rotationRows(input));
}
console.log(JSON.stringify(out));
"""


def _run(job):
    if shutil.which("node") is None:
        pytest.skip("node is needed to run the plugin's JavaScript (install Node.js)")
    run = subprocess.run(["bash", os.path.join(ROOT, "scripts", "setup_node.sh")], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    text = SCRIPT.replace("%(src)s/transfer_source.js", json.dumps(f"file://{SRC}/transfer_source.js"))
    text = text.replace("%(src)s/format.js", json.dumps(f"file://{SRC}/format.js"))
    text = text.replace("%(src)s/rotation_input.js", json.dumps(f"file://{SRC}/rotation_input.js"))
    # The script lives in web/ so that 'three' resolves from web/node_modules.
    script = os.path.join(ROOT, "web", ".test_web_node.mjs")
    with open(script, "w") as f:
        f.write(text)
    try:
        run = subprocess.run(["node", script], input=json.dumps(job), capture_output=True, text=True, timeout=120)
    finally:
        os.remove(script)
    assert run.returncode == 0, run.stderr[-3000:]
    return json.loads(run.stdout)


def _decode_case(encoding, order, vertices, rng, interleaved=False):
    count = (order * order + 3) // 4
    values = rng.normal(size=(count, vertices, 4)) * rng.uniform(0.01, 3.0, size=(count, 1, 4))
    component, k, _dtype = quantise.ENCODINGS.get(encoding, (5126, None, None))
    attributes, table, expected = [], [], []
    for rows in values:
        if k is None:
            attributes.append(rows.astype(np.float32).ravel().tolist())
            expected.append(rows.astype(np.float32).astype(np.float64))
            continue
        q, offset, scale = quantise.encode(rows, k)
        attributes.append(q.astype(int).ravel().tolist())
        table.append({"offset": offset.tolist(), "scale": scale.tolist()})
        expected.append(quantise.decode(q, offset, scale, k))
    meta = {"version": 2 if k else 1, "order": order, "attributes": [f"_PRT_T{i}" for i in range(count)]}
    meta["transfer_encoding"] = encoding
    if k:
        meta["decode"] = table
    case = {"vertices": vertices, "attributes": attributes, "meta": meta, "interleaved": interleaved}
    return case, np.stack(expected), values


def test_plugin_decodes_the_transfer_as_the_export_encodes_it():
    """The plugin's transfer texture holds, per vertex and vec4, what quantise.decode makes of the
    stored integers (float32: the values), for plain and interleaved attributes, packed
    perRow vertices a texture row; so the decoded values are within half a step of the original."""
    rng = np.random.default_rng(11)
    cases = [
        _decode_case("snorm16", 8, 37, rng),
        _decode_case("snorm8", 4, 29, rng),
        _decode_case("float32", 3, 20, rng),
        _decode_case("snorm16", 4, 23, rng, interleaved=True),
    ]
    out = _run({"decode": [c for c, _e, _v in cases], "checks": [], "rotations": [], "packed": []})
    for (case, expected, original), got in zip(cases, out["decoded"], strict=True):
        count, vertices = expected.shape[0], case["vertices"]
        per_row, width = got["perRow"], got["width"]
        assert per_row == 64 // count and width == per_row * count
        data = np.array(got["data"]).reshape(-1, width, 4)
        texels = np.array(
            [[data[v // per_row, (v % per_row) * count + k] for k in range(count)] for v in range(vertices)]
        )
        want = expected.transpose(1, 0, 2)
        assert np.abs(texels - want).max() <= 1e-6 * np.abs(want).max()
        steps = {"snorm16": 32767, "snorm8": 127}
        if case["meta"]["transfer_encoding"] in steps:
            scale = np.array([d["scale"] for d in case["meta"]["decode"]])[None]
            assert (
                np.abs(texels - original.transpose(1, 0, 2))
                <= 0.5001 * scale / steps[case["meta"]["transfer_encoding"]] + 1e-6
            ).all()


def test_format_checks_say_what_is_wrong():
    """readLighting and readTransfer accept good blocks and say what is wrong with each bad one;
    a mesh's contact tangent is found under GLTFLoader's lowercase name, or is warned about."""
    good_lighting = {"version": 1, "order": 2, "coefficients": [[0.1, 0.2, 0.3]] * 4, "lights": []}
    light = {"direction": [0, 1, 0], "power": [1, 1, 1], "angle": 0.01, "samples": None, "views": []}
    transfer = {"version": 2, "order": 2, "attributes": ["_PRT_T0"], "transfer_encoding": "float32"}
    attrs = ["_prt_t0"]
    cases = [
        ("lighting", good_lighting, None, "ok"),
        ("lighting", dict(good_lighting, lights=[light]), None, "ok"),
        ("lighting", None, None, "no PRT lighting"),
        ("lighting", "garbage", None, "is not an object"),
        ("lighting", dict(good_lighting, version=2), None, "format version 2, newer than this plugin reads (1)"),
        ("lighting", dict(good_lighting, coefficients=[[0.1, 0.2, 0.3]] * 3), None, "3 rows, not a square"),
        ("lighting", dict(good_lighting, order=3), None, "declares order 3 but holds 4 coefficients"),
        ("lighting", dict(good_lighting, coefficients=[[0.1, "x", 0.3]] * 4), None, "not a list of [r, g, b] rows"),
        ("lighting", dict(good_lighting, lights=[dict(light, power=[1, 1])]), None, "light 0 lacks"),
        ("lighting", dict(good_lighting, lights_coefficients="garbage"), None, "lights coefficients are not a list"),
        (
            "lighting",
            dict(good_lighting, lights=[dict(light, views=[{"direction": [0, 1, 0], "angle": 0.1, "samples": [3]}])]),
            None,
            "indexes samples it does not have",
        ),
        ("transfer", transfer, attrs, "ok"),
        ("transfer", dict(transfer, version=4), attrs, "format version 4, newer than this plugin reads (3)"),
        ("transfer", dict(transfer, order=3), attrs, "order 3 needs 3 transfer attributes, it lists 1"),
        ("transfer", transfer, [], "needs the attributes _PRT_T0"),
        ("transfer", dict(transfer, transfer_encoding="snorm16"), attrs, "no complete decode table"),
        ("transfer", dict(transfer, transfer_encoding="half"), attrs, "encoding 'half' is unknown"),
        ("transfer", dict(transfer, bounce_channels=3), attrs, "bounced transfer is inconsistent"),
        # The contact tangent (docs/export.md, "Contact tangent"): optional; a broken one is drawn without.
        ("transfer", dict(transfer, contact="_PRT_CONTACT"), attrs + ["_prt_contact"], "ok, contact _prt_contact"),
        (
            "transfer",
            dict(transfer, contact="_PRT_CONTACT"),
            attrs,
            "warning: its contact tangent _PRT_CONTACT is missing",
        ),
    ]
    # Texel transfers (docs/export.md, "Texel transfer"): two PNG textures, a TEXCOORD_1 ("uv1").
    document = {"textures": [{"source": 0}, {"source": 1}], "images": [{"bufferView": 3}, {"bufferView": 4}]}
    decode = [{"offset": [0, 0, 0, 0], "scale": [1, 1, 1, 1]}]
    texel = {"texcoord": 1, "resolution": 8, "tiles": [1, 1], "textures": [0, 1], "decode": decode}
    good = {"version": 3, "order": 2, "domain": "TEXEL", "attributes": [], "transfer_encoding": "unorm16_png"}
    good["texel"] = texel
    texel_cases = [
        (good, ["uv1"], "ok"),
        (good, ["uv"], "lightmap UV map TEXCOORD_1 is missing"),
        (dict(good, transfer_encoding="unorm8_png"), ["uv1"], "needs 1 texture(s) in the file"),
        (dict(good, texel=dict(texel, textures=[0, 7])), ["uv1"], "needs 2 texture(s) in the file"),
        (dict(good, texel=dict(texel, decode=[])), ["uv1"], "no complete decode table (1 tiles)"),
        (dict(good, texel=dict(texel, resolution=0)), ["uv1"], "texel resolution is bad"),
        (dict(good, transfer_encoding="snorm16"), ["uv1"], "texel encoding 'snorm16' is unknown"),
        ({k: v for k, v in good.items() if k != "texel"}, ["uv1"], "has no texel block"),
    ]
    # A bounced texel transfer: per channel its own planes and decode table.
    bounced = dict(good, bounce_channels=1, texel=dict(texel, bounce_textures=[[1, 0]], bounce_decode=[decode]))
    texel_cases += [
        (bounced, ["uv1"], "ok"),
        (dict(good, bounce_channels=1), ["uv1"], "declares bounced light without its bounce planes"),
        (dict(bounced, bounce_channels=3), ["uv1"], "declares 3 bounce channels, it has 1"),
        (dict(bounced, bounce_channels=2), ["uv1"], "has 2 bounce channels"),
        (dict(bounced, texel=dict(bounced["texel"], bounce_textures=[[1]])), ["uv1"], "bounce 0 needs 2 texture(s)"),
        (dict(bounced, texel=dict(bounced["texel"], bounce_decode=[[]])), ["uv1"], "bounce 0 has no complete decode"),
    ]
    cases += [("transfer", meta, [], message) for meta, _uvs, message in texel_cases]
    checks = [{"kind": kind, "meta": meta, "attributes": a} for kind, meta, a, _m in cases]
    for check, (_meta, uvs, _m) in zip(checks[len(cases) - len(texel_cases) :], texel_cases, strict=True):
        check.update(uvs=uvs, json=document)
    # (undefined, not null, for a missing block)
    checks[2].pop("meta")
    out = _run({"decode": [], "checks": checks, "rotations": []})
    for (_kind, _meta, _a, message), got in zip(cases, out["checks"], strict=True):
        if message.startswith(("ok", "warning: ")):
            assert got == message if message == "ok" else got.startswith(message), (message, got)
        else:
            assert got.startswith("FormatError: ") and message in got, (message, got)


def test_rotation_inputs_are_the_same_rotation():
    """setLightingRotation's inputs: an Euler (three.js's 'XYZ' order, the matrix Rx Ry Rz), a
    quaternion, a Matrix3 and a Matrix4 (its upper 3x3) give the row-major matrix numpy makes of
    them (Rodrigues' formula, core.rotation.axis_angle_matrix)."""
    a, b, c = 0.4, -1.1, 2.3
    rx = rotation.axis_angle_matrix([1, 0, 0], a)
    ry = rotation.axis_angle_matrix([0, 1, 0], b)
    rz = rotation.axis_angle_matrix([0, 0, 1], c)
    euler = rx @ ry @ rz
    axis, angle = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8]), 1.3
    quat = [*(np.sin(angle / 2) * axis), np.cos(angle / 2)]
    m4 = np.eye(4)
    m4[:3, :3] = euler.T
    m4[:3, 3] = [5, 6, 7]
    job = {
        "decode": [],
        "checks": [],
        "rotations": [
            {"kind": "euler", "values": [a, b, c]},
            {"kind": "quaternion", "values": quat},
            {"kind": "matrix3", "values": euler.ravel().tolist()},
            {"kind": "matrix4", "values": m4.ravel().tolist()},
        ],
    }
    out = _run(job)["rotations"]
    np.testing.assert_allclose(np.array(out[0]).reshape(3, 3), euler, atol=1e-12)
    np.testing.assert_allclose(np.array(out[1]).reshape(3, 3), rotation.axis_angle_matrix(axis, angle), atol=1e-12)
    np.testing.assert_allclose(np.array(out[2]).reshape(3, 3), euler, atol=1e-12)
    np.testing.assert_allclose(np.array(out[3]).reshape(3, 3), euler.T, atol=1e-12)


def test_packed_source_folds_the_decoding_into_the_light():
    """The packed source's integers (two 16-bit values an int32) dotted with lightFor's rows, plus
    its constant, as the shader computes them, are sum_i L_i t_i of the decoded transfer, for the
    direct block and for a bounced block (channel c against block blocks[c])."""
    rng = np.random.default_rng(23)
    order, vertices = 5, 31
    count = (order * order + 3) // 4  # 7: the last int32's high half holds the next block's first vec4
    blocks = 2  # direct and one bounced channel
    attributes, table, decoded = [], [], []
    for _ in range(count * blocks):
        rows = rng.normal(size=(vertices, 4)) * rng.uniform(0.01, 2.0, 4) + rng.normal(size=4)
        q, offset, scale = quantise.encode(rows, 32767)
        attributes.append(q.astype(int).ravel().tolist())
        table.append({"offset": offset.tolist(), "scale": scale.tolist()})
        decoded.append(quantise.decode(q, offset, scale, 32767))
    meta = {
        "version": 2,
        "order": order,
        "attributes": [f"_PRT_T{i}" for i in range(count)],
        "bounce_attributes": [f"_PRT_T{i}" for i in range(count, 2 * count)],
        "bounce_channels": 1,
        "transfer_encoding": "snorm16",
        "decode": table,
    }
    light = rng.normal(size=(order * order, 3))
    cases = [
        {"vertices": vertices, "attributes": attributes, "meta": meta, "light": light.tolist(), "blocks": b}
        for b in ([0, 0, 0], [1, 1, 1])
    ]
    out = _run({"decode": [], "checks": [], "rotations": [], "packed": cases})["packed"]
    t = np.stack(decoded)  # (count * blocks, vertices, 4)
    for case, got in zip(cases, out, strict=True):
        assert got["kind"] == "packed" and got["slots"] == count  # ceil(14 / 2)
        block = case["blocks"][0]
        transfer = t[block * count : (block + 1) * count].transpose(1, 0, 2).reshape(vertices, -1)[:, : order * order]
        want = transfer @ light
        assert np.abs(np.array(got["radiance"]) - want).max() < 1e-9 * np.abs(want).max()
