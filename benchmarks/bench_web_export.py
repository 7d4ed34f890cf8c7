"""Web export benchmark: .glb size per vertex and the error each transfer encoding adds, at orders 4 and 8, and Blender's Draco.

    .venv/bin/python benchmarks/bench_web_export.py [--orders 4 8] [--samples 64]

The demo scene (scripts/demo.py: Suzanne on a 60x60 ground under forest.exr) is baked at each
order and exported with the transfer as float32, snorm16 and snorm8 (blender/export/quantise.py),
and float32 again through Blender's exporter's Draco compression (its own option; the exporter
has no EXT_meshopt_compression). Sizes are of the whole .glb (positions, normals, indices, the
lighting and the 128 px environment cube included) and of the same file gzipped (what an HTTP
server with compression sends). The error is the per-vertex radiance max(0, L . t) (the world
light in each node's frame, as the viewer shades) from the decoded transfer against float32's, as
a fraction of the mean radiance: the viewer interpolates it linearly over triangles, so that is
what the quantisation adds to the viewer's image against api.render_view.
"""

import argparse
import gzip
import os
import sys
import tempfile

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import bpy
import numpy as np

import prt_addon
from prt_addon import api
from prt_addon.blender.export import glb, gltf, quantise
from prt_addon.core import frames, rotation

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
import demo

COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
TYPES = {5126: (np.float32, None), 5122: (np.int16, 32767), 5120: (np.int8, 127)}


def _accessor(document, binary, index):
    acc = document["accessors"][index]
    view = document["bufferViews"][acc["bufferView"]]
    dtype, k = TYPES[acc["componentType"]]
    width = COMPONENTS[acc["type"]]
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    values = np.frombuffer(binary, dtype, acc["count"] * width, start).reshape(-1, width).astype(np.float64)
    return values if k is None else np.maximum(values / k, -1.0)


def radiance(path):
    """{mesh name: (V, 3) per-vertex radiance max(0, L_local . t)} of a file, decoded as the plugin does."""
    document, chunks = glb.read(path)
    binary = chunks[0][1]
    lighting = np.array(document["scenes"][0]["extras"]["PRT_lighting"]["coefficients"])
    out = {}
    for node in document["nodes"]:
        if "mesh" not in node:
            continue
        mesh = document["meshes"][node["mesh"]]
        meta = mesh.get("extras", {}).get("PRT_lighting")
        if meta is None:
            continue
        n = meta["order"]
        x, y, z, w = node.get("rotation", [0, 0, 0, 1])
        r = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
            ]
        ) @ np.diag(node.get("scale", [1, 1, 1]))
        q, mirrored = frames.frame_rotation(r)
        light = np.zeros((n * n, 3))
        m = min(n * n, len(lighting))
        light[:m] = lighting[:m]
        local = rotation.rotation_matrix(q.T, n) @ light
        assert not mirrored
        for prim in mesh["primitives"]:
            columns = []
            for k, name in enumerate(meta["attributes"]):
                values = _accessor(document, binary, prim["attributes"][name])
                if meta.get("transfer_encoding", "float32") != "float32":
                    values = np.asarray(meta["decode"][k]["offset"]) + np.asarray(meta["decode"][k]["scale"]) * values
                columns.append(values)
            t = np.hstack(columns)[:, : n * n]
            out[mesh["name"]] = np.maximum(t @ local, 0.0)
    return out


def draco_export(path):
    """float32 through Blender's exporter with its Draco compression (default levels); its size
    and whether the transfer attributes went into the compressed stream."""
    original = gltf._run_exporter

    def with_draco(target, meshes):
        return bpy.ops.export_scene.gltf(
            filepath=target,
            **gltf.EXPORTER_OPTIONS,
            export_active_vertex_color_when_no_material=False,
            export_draco_mesh_compression_enable=True,
        )

    gltf._run_exporter = with_draco
    try:
        gltf.export_gltf(path, transfer="float32")
    finally:
        gltf._run_exporter = original
    document, _chunks = glb.read(path)
    prims = [p for m in document["meshes"] for p in m["primitives"]]
    compressed = all(
        name in p.get("extensions", {}).get("KHR_draco_mesh_compression", {}).get("attributes", {})
        for p in prims
        for name in p["attributes"]
        if name.startswith("_PRT_T")
    )
    return os.path.getsize(path), compressed


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--orders", type=int, nargs="+", default=[4, 8])
    parser.add_argument("--samples", type=int, default=64)
    args = parser.parse_args()
    prt_addon.register()
    scene = demo.build_scene(demo.bundled_hdri_path("forest"))
    objects = [scene.objects["Suzanne"], scene.objects["Ground"]]
    folder = tempfile.mkdtemp(prefix="prt_bench_web_")
    print(
        "order | encoding | .glb bytes | bytes/vertex | gzipped bytes/vertex | radiance error mean / p99 / max (% of mean)"
    )
    for order in args.orders:
        api.project_world(order=order)
        api.bake(objects, order=order, samples=args.samples)
        paths = {
            e: gltf.export_gltf(os.path.join(folder, f"o{order}_{e}.glb"), transfer=e)
            for e in quantise.TRANSFER_ENCODINGS
        }
        document, _chunks = glb.read(paths["float32"])
        vertices = sum(
            document["accessors"][p["attributes"]["POSITION"]]["count"]
            for m in document["meshes"]
            for p in m["primitives"]
        )
        truth = radiance(paths["float32"])
        level = np.mean(np.concatenate([v.ravel() for v in truth.values()]))
        for encoding, path in paths.items():
            size = os.path.getsize(path)
            with open(path, "rb") as f:
                zipped = len(gzip.compress(f.read(), 6))
            document, _chunks = glb.read(path)
            cube = sum(document["bufferViews"][im["bufferView"]]["byteLength"] for im in document.get("images", []))
            got = radiance(path)
            diff = np.concatenate([np.abs(got[k] - truth[k]).max(axis=1) for k in truth]) / level
            print(
                f"{order} | {encoding} | {size} | {size / vertices:.1f} | {(size - cube) / vertices:.1f} | "
                f"{zipped / vertices:.1f} | "
                f"{100 * diff.mean():.4f} / {100 * np.percentile(diff, 99):.4f} / {100 * diff.max():.4f}"
            )
        size, compressed = draco_export(os.path.join(folder, f"o{order}_draco.glb"))
        print(
            f"{order} | float32 + Draco | {size} | {size / vertices:.1f} | - | transfer in the Draco stream: {compressed}"
        )
        print(f"  ({vertices} glTF vertices)")
    sys.stdout.flush()
    os._exit(0)  # (bpy 4.2 crashes at exit after a glTF export: docs/export.md)


if __name__ == "__main__":
    main()
