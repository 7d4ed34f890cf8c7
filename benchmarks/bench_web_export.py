"""Web export benchmark: .glb size per vertex and the error each transfer encoding adds, at orders 4 and 8, and Blender's Draco.

    .venv/bin/python benchmarks/bench_web_export.py [--orders 4 8] [--samples 64]

The demo scene (scripts/demo.py: Suzanne on a 60x60 ground under forest.exr) is baked at each
order and exported with the transfer as float32, snorm16 and snorm8 (blender/export/quantise.py),
and float32 again through Blender's exporter's Draco compression (its own option; the exporter
has no EXT_meshopt_compression), at its default 12 bits for generic attributes and at 16, read
back through Blender's importer (which decodes Draco; each vertex matched to the nearest float32
vertex of the same mesh). Sizes are of the whole .glb (positions, normals, indices, the
lighting and the 128 px environment cube included) and of the same file gzipped (what an HTTP
server with compression sends). The error is the per-vertex radiance max(0, L . t) (the world
light in each node's frame, as the viewer shades) from the decoded transfer against float32's, as
a fraction of the mean radiance: the viewer interpolates it linearly over triangles, so that is
what the quantisation adds to the viewer's image against api.render_view. With --texels R the
ground is then baked per texel (R x R, into a copy of its UV map) and exported as PNG planes
(blender/export/texels.py): bytes per texel and the per-texel radiance error of the 16- and 8-bit
encodings (the viewer relights each texel and looks the texels up bilinearly, so that is what
they add to its image). With --room R the same for the low-poly room of the texel tests, every
object per texel at R x R (a lightmap busy with shadows and contacts).
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
from prt_addon.blender.export import glb, gltf, quantise, texels
from prt_addon.core.sh import frames, rotation

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


def _node_light(node, n, lighting):
    """The world light (order n) in a glTF node's frame (its rotation and scale), and whether the
    frame is mirrored."""
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
    return rotation.rotation_matrix(q.T, n) @ light, mirrored


def local_lights(path):
    """{node name: (glTF mesh name, (n*n, 3) the world light in the node's frame)} of a file's baked meshes."""
    document, _chunks = glb.read(path)
    lighting = np.array(document["scenes"][0]["extras"]["PRT_lighting"]["coefficients"])
    out = {}
    for node in document["nodes"]:
        meta = document["meshes"][node["mesh"]].get("extras", {}).get("PRT_lighting") if "mesh" in node else None
        if meta is None:
            continue
        local, _mirrored = _node_light(node, meta["order"], lighting)
        out[node["name"]] = (document["meshes"][node["mesh"]]["name"], local)
    return out


def positions(path):
    """{mesh name: (V, 3) glTF-local vertex positions} of a file's baked meshes, in radiance()'s order."""
    document, chunks = glb.read(path)
    out = {}
    for mesh in document["meshes"]:
        if "PRT_lighting" in mesh.get("extras", {}):
            rows = [_accessor(document, chunks[0][1], p["attributes"]["POSITION"]) for p in mesh["primitives"]]
            out[mesh["name"]] = np.concatenate(rows)
    return out


def draco_radiance(path, lights, order):
    """{mesh name: ((V, 3) glTF-local positions, (V, 3) radiance)} of a Draco file as Blender's
    importer decodes it (the _PRT_Tk attributes, float32 before compression); the imported
    objects are removed again."""
    before = set(bpy.data.objects)
    bpy.ops.import_scene.gltf(filepath=path)
    out = {}
    try:
        for obj in set(bpy.data.objects) - before:
            node = obj.name if obj.name in lights else obj.name.rsplit(".", 1)[0]  # ("Suzanne.001")
            if obj.type != "MESH" or node not in lights:
                continue
            mesh_name, light = lights[node]
            mesh = obj.data
            co = np.empty(len(mesh.vertices) * 3, np.float32)
            mesh.vertices.foreach_get("co", co)
            co = co.reshape(-1, 3)
            columns = []
            for k in range(-(-order * order // 4)):
                attr = mesh.attributes[f"_PRT_T{k}"]
                assert attr.domain == "POINT", attr.domain
                values = np.empty(len(attr.data) * 4, np.float32)
                attr.data.foreach_get("color" if attr.data_type.endswith("COLOR") else "vector", values)
                columns.append(values.reshape(-1, 4))
            t = np.hstack(columns)[:, : order * order].astype(np.float64)
            out[mesh_name] = (np.c_[co[:, 0], co[:, 2], -co[:, 1]], np.maximum(t @ light, 0.0))
    finally:
        for obj in set(bpy.data.objects) - before:
            data = obj.data
            bpy.data.objects.remove(obj)
            if isinstance(data, bpy.types.Mesh) and data.users == 0:
                bpy.data.meshes.remove(data)
    return out


def draco_error(path, truth, where, lights, order):
    """(mean, p99, max) of the Draco file's per-vertex radiance against float32's (the nearest
    float32 vertex of the same mesh, by position), as fractions of the mean radiance."""
    from scipy.spatial import cKDTree

    decoded = draco_radiance(path, lights, order)
    level = np.mean(np.concatenate([v.ravel() for v in truth.values()]))
    diffs = []
    for name, (pos, got) in decoded.items():
        _d, nearest = cKDTree(where[name]).query(pos)
        diffs.append(np.abs(got - truth[name][nearest]).max(axis=1) / level)
    diff = np.concatenate(diffs)
    return diff.mean(), np.percentile(diff, 99), diff.max()


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
        local, mirrored = _node_light(node, n, lighting)
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


def draco_export(path, bits=12):
    """float32 through Blender's exporter with its Draco compression (default levels, `bits` for
    generic attributes such as the transfer: 12 is the exporter's default); its size and whether
    the transfer attributes went into the compressed stream."""
    original = gltf._run_exporter

    def with_draco(target, meshes):
        return bpy.ops.export_scene.gltf(
            filepath=target,
            **gltf.EXPORTER_OPTIONS,
            export_active_vertex_color_when_no_material=False,
            export_draco_mesh_compression_enable=True,
            export_draco_generic_quantization=bits,
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


def texel_figures(scene, folder, order, samples, resolution):
    """The ground baked per texel (resolution^2 into a copy of its UV map) beside Suzanne per
    vertex: per texel encoding, the PNG planes' bytes per texel, the whole .glb, and the radiance
    error max(0, L . t) per texel (glTF frame) of the decoded coefficients against the float ones."""
    from prt_addon.blender.scene import storage, texel_storage
    from prt_addon.core.transfer import texel_encoding

    ground = scene.objects["Ground"]
    if ground.data.uv_layers.get("Lightmap") is None:
        ground.data.uv_layers.new(name="Lightmap")
    api.bake([ground], order=order, samples=samples, target="TEXELS", uv_map="Lightmap", resolution=resolution)
    bake, _ = storage.read_bake_record(ground.data)
    n2 = order * order
    values = texel_storage.read_texel_transfer(bake).astype(np.float64)
    values = gltf.to_gltf_frame(values.reshape(-1, n2).T).T
    rows = []
    for transfer in ("snorm16", "snorm8"):
        path = gltf.export_gltf(os.path.join(folder, f"o{order}_texel_{transfer}.glb"), transfer=transfer)
        document, _chunks = glb.read(path)
        lighting = np.array(document["scenes"][0]["extras"]["PRT_lighting"]["coefficients"])[:n2]
        planes = sum(
            document["bufferViews"][im["bufferView"]]["byteLength"]
            for im in document["images"]
            if im["name"].startswith("PRT_transfer")
        )
        encoding = texels.encoding_for(transfer)
        stored, offset, scale = texel_encoding.encode(values, texel_encoding.PLANES[encoding])
        decoded = texel_encoding.decode(stored, offset, scale)
        truth = np.maximum(values @ lighting[: len(values[0])], 0.0)
        diff = np.abs(np.maximum(decoded @ lighting, 0.0) - truth).max(axis=1) / truth.mean()
        rows.append((encoding, planes / resolution**2, os.path.getsize(path), diff))
    print(f"  texels: the ground at {resolution}^2, order {order} (raw float32 {4 * n2} bytes/texel)")
    for encoding, per_texel, size, diff in rows:
        print(
            f"  {encoding}: {per_texel:.1f} PNG bytes/texel, .glb {size} bytes; radiance error mean / p99 / max "
            f"{100 * diff.mean():.4f} / {100 * np.percentile(diff, 99):.4f} / {100 * diff.max():.4f} % of the mean"
        )
    api.bake([ground], order=order, samples=samples)  # (per vertex again for the next order)


def room_figures(folder, orders, samples, resolution):
    """The low-poly room of the texel tests (tests/helpers/texel_scenes.py: every object per
    texel, resolution^2 each, Smart UV Project lightmaps) under forest.exr: PNG bytes per texel
    and the per-texel radiance error of each texel encoding."""
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))
    from helpers import texel_scenes

    from prt_addon.blender.scene import storage, texel_storage
    from prt_addon.core.transfer import texel_encoding

    scene = demo.build_scene(demo.bundled_hdri_path("forest"))
    for name in ("Suzanne", "Ground"):
        bpy.data.objects.remove(scene.objects[name])
    objects = texel_scenes.low_poly_room(bpy)
    for order in orders:
        api.project_world(order=order)
        api.bake(objects, order=order, samples=samples, target="TEXELS", uv_map="Lightmap", resolution=resolution)
        n2 = order * order
        for transfer in ("snorm16", "snorm8"):
            path = gltf.export_gltf(os.path.join(folder, f"room_o{order}_{transfer}.glb"), objects, transfer=transfer)
            document, _chunks = glb.read(path)
            lighting = np.array(document["scenes"][0]["extras"]["PRT_lighting"]["coefficients"])[:n2]
            planes = sum(
                document["bufferViews"][im["bufferView"]]["byteLength"]
                for im in document["images"]
                if im["name"].startswith("PRT_transfer")
            )
            encoding = texels.encoding_for(transfer)
            truth, got = [], []
            for obj in objects:
                bake, _ = storage.read_bake_record(obj.data)
                values = texel_storage.read_texel_transfer(bake).astype(np.float64).reshape(-1, n2)
                values = gltf.to_gltf_frame(values.T).T
                stored, offset, scale = texel_encoding.encode(values, texel_encoding.PLANES[encoding])
                truth.append(np.maximum(values @ lighting, 0.0))
                got.append(np.maximum(texel_encoding.decode(stored, offset, scale) @ lighting, 0.0))
            truth, got = np.concatenate(truth), np.concatenate(got)
            diff = np.abs(got - truth).max(axis=1) / truth.mean()
            texel_count = len(objects) * resolution**2
            print(
                f"  room ({len(objects)} objects at {resolution}^2), order {order}, {encoding}: "
                f"{planes / texel_count:.1f} PNG bytes/texel (raw planes {2 * n2 if '16' in encoding else n2}); "
                f"radiance error mean / p99 / max {100 * diff.mean():.4f} / {100 * np.percentile(diff, 99):.4f} / "
                f"{100 * diff.max():.4f} % of the mean"
            )


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--orders", type=int, nargs="+", default=[4, 8])
    parser.add_argument("--samples", type=int, default=64)
    parser.add_argument("--texels", type=int, default=256, help="the ground's texel bake resolution (0: none)")
    parser.add_argument("--room", type=int, default=64, help="the texel room's resolution per object (0: none)")
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
        lights, where = local_lights(paths["float32"]), positions(paths["float32"])
        for bits in (12, 16):
            draco = os.path.join(folder, f"o{order}_draco{bits}.glb")
            size, compressed = draco_export(draco, bits)
            mean, p99, top = draco_error(draco, truth, where, lights, order)
            print(
                f"{order} | float32 + Draco ({bits}-bit generic) | {size} | {size / vertices:.1f} | - | - | "
                f"{100 * mean:.4f} / {100 * p99:.4f} / {100 * top:.4f} (transfer in the Draco stream: {compressed})"
            )
        print(f"  ({vertices} glTF vertices)")
        if args.texels:
            texel_figures(scene, folder, order, args.samples, args.texels)
    if args.room:
        room_figures(folder, args.orders, args.samples, args.room)
    sys.stdout.flush()
    os._exit(0)  # (bpy 4.2 crashes at exit after a glTF export: docs/export.md)


if __name__ == "__main__":
    main()
