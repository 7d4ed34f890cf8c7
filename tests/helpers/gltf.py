"""glTF tools for the tests: a .glb read back, rows compared with the stored transfer, Khronos' validator."""

import numpy as np

COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


def _world(bpy):
    world = bpy.data.worlds.new("PRT test world")
    if not world.node_tree:
        world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.5, 0.6, 0.7, 1.0)
    bpy.context.scene.world = world


def _read_glb(path):
    from prt_addon.blender.export import glb

    document, chunks = glb.read(path)
    binary = chunks[0][1]

    def accessor(index):
        """The accessor's values: floats, or a normalised integer one's q / K (glTF's decoding)."""
        acc = document["accessors"][index]
        view = document["bufferViews"][acc["bufferView"]]
        dtype, k = {5126: (np.float32, None), 5122: (np.int16, 32767), 5120: (np.int8, 127)}[acc["componentType"]]
        assert (k is not None) == acc.get("normalized", False)
        width = COMPONENTS[acc["type"]]
        start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
        assert view.get("byteStride", np.dtype(dtype).itemsize * width) == np.dtype(dtype).itemsize * width
        values = np.frombuffer(binary, dtype, acc["count"] * width, start).reshape(-1, width)
        return values if k is None else np.maximum(values.astype(np.float64) / k, -1.0)

    return document, accessor


def _transfer(document, accessor, mesh, prim):
    """A primitive's transfer (rows of n*n, glTF frame) decoded as docs/export.md says: float32
    as stored, a quantised one as offset + scale * (q / K) per attribute and component."""
    meta = mesh["extras"]["PRT_lighting"]
    columns = []
    for k, name in enumerate(meta["attributes"]):
        values = accessor(prim["attributes"][name]).astype(np.float64)
        if meta.get("transfer_encoding", "float32") != "float32":
            values = np.asarray(meta["decode"][k]["offset"]) + np.asarray(meta["decode"][k]["scale"]) * values
        columns.append(values)
    return np.hstack(columns)[:, : meta["order"] ** 2]


def _stored_rows(obj):
    """(positions (E, 3) local, Blender frame; transfer (E, n*n)) of an object's bake."""
    from prt_addon.blender.scene import storage

    mesh = obj.data
    bake, _ = storage.read_bake_record(mesh)
    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    if bake.domain == "CORNER":
        corner = np.empty(len(mesh.loops), np.int32)
        mesh.loops.foreach_get("vertex_index", corner)
        co = co[corner]
    return co.astype(np.float64), storage.read_transfer(mesh).astype(np.float64)


def _assert_rows_match(stored_pos, stored_t, pos, t, tol=2e-5):
    """Every exported row (position, transfer) is a stored row, and every stored row is exported."""
    keys = {}
    for i, p in enumerate(np.round(stored_pos, 4)):
        keys.setdefault(tuple(p), []).append(i)
    used = np.zeros(len(stored_pos), bool)
    for p, row in zip(np.round(pos, 4), t):
        candidates = keys.get(tuple(p))
        assert candidates, f"exported position {p} is not a vertex of the mesh"
        err = np.abs(stored_t[candidates] - row).max(axis=1)
        assert err.min() < tol * max(1.0, np.abs(row).max()), (p, err.min())
        used[np.array(candidates)[err < tol * max(1.0, np.abs(row).max())]] = True
    assert used.all(), f"{(~used).sum()} stored rows are not in the export"


def _from_gltf(values):
    from prt_addon.blender.export import gltf

    n = int(round(np.sqrt(values.shape[1])))
    from prt_addon.core.sh import rotation

    return (rotation.rotation_matrix(gltf.BLENDER_TO_GLTF, n).T @ values.T).T


VALIDATE_JS = """
const fs = require('fs');
const validator = require('gltf-validator');
validator.validateBytes(new Uint8Array(fs.readFileSync(process.argv[1])), {maxIssues: 100})
  .then((report) => console.log(JSON.stringify(report.issues)))
  .catch((error) => { console.error(error); process.exit(1); });
"""
