"""Image albedo benchmark: the frame cost of a mesh drawn with an image on its Base Color against
the same mesh in a constant colour, and the cost of building its GPU data (per corner, the image).

    .venv/bin/python benchmarks/bench_albedo.py [--triangles 200000] [--frames 15] [--size 512] [--image 1024]

Two copies of one UV sphere, each with its own mesh (the batches are cached per mesh), one with a
checker image of --image pixels on its Base Color and one constant; the same unshadowed order-4
transfer and light. Their render_view frames (offscreen draw and read-back) are interleaved and
the ratio is of medians in this one run; absolute times are for this machine only (llvmpipe).
"""

import argparse
import math
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import bpy
import numpy as np

import prt_addon
from prt_addon.blender.display import gpu_cache, offscreen
from prt_addon.blender.scene import lighting
from prt_addon.core.sh import analytic, basis as sh

ORDER = 4


def sphere(name, triangles):
    import bmesh

    segments = int(round(math.sqrt(triangles)))
    rings = max(3, triangles // (2 * segments) + 1)
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=segments, v_segments=rings, radius=1.0, calc_uvs=True)
    bm.to_mesh(mesh)
    bm.free()
    mesh.shade_smooth()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def write_transfer(obj):
    mesh = obj.data
    co = np.empty(3 * len(mesh.vertices), dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    n = co.reshape(-1, 3).astype(np.float64)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    zonal = analytic.clamped_cosine_zonal(ORDER)
    bands = sh.band_of_index(ORDER)
    t = sh.sh_basis(n, ORDER) * (np.sqrt(4 * np.pi / (2 * bands + 1)) * zonal[bands])[None]
    count = ORDER * ORDER // 4
    for k in range(count):
        mesh.color_attributes.new(f"prt_t{k:02d}", "FLOAT_COLOR", "POINT")
    for k in range(count):
        mesh.attributes[f"prt_t{k:02d}"].data.foreach_set("color", t[:, 4 * k : 4 * k + 4].astype(np.float32).ravel())
    from prt_addon.blender.scene.mesh_read import topology_fingerprint

    mesh["prt_bake"] = {
        "order": ORDER, "count": count, "domain": "POINT", "samples": 0, "direction_set": "analytic", "seed": 0,
        "shadows": False, "backend": "NONE", "fingerprint": topology_fingerprint(mesh), "seconds": 0.0,
        "rays_traced": 0, "rays_skipped": 0, "error_estimate": 0.0,
    }  # fmt: skip


def checker_material(size):
    image = bpy.data.images.new("checker", size, size)
    i = (np.arange(size) * 16 // size) % 2
    rgb = np.where((i[:, None] ^ i[None, :])[..., None] == 1, [0.9, 0.2, 0.1, 1.0], [0.1, 0.3, 0.9, 1.0])
    image.pixels.foreach_set(rgb.astype(np.float32).ravel())
    mat = bpy.data.materials.new("textured")
    if mat.node_tree is None:
        mat.use_nodes = True
    tree = mat.node_tree
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    tree.links.new(tex.outputs["Color"], tree.nodes["Principled BSDF"].inputs["Base Color"])
    return mat


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--triangles", type=int, default=200000)
    parser.add_argument("--frames", type=int, default=15)
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--image", type=int, default=1024)
    args = parser.parse_args()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    prt_addon.register()
    assert offscreen.ensure_gpu()
    scene = bpy.context.scene
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    cam.location, cam.rotation_euler = (0.0, -4.0, 0.0), (math.pi / 2, 0.0, 0.0)
    scene.camera = cam
    scene.render.resolution_x = scene.render.resolution_y = args.size
    world = bpy.data.worlds.new("World")
    scene.world = world
    lighting.set_light_override(scene, analytic.cap_coeffs(ORDER, (1, 0, 0), 0.3, radiance=(5, 4, 3)))
    plain, textured = sphere("plain", args.triangles), sphere("textured", args.triangles)
    for obj in (plain, textured):
        write_transfer(obj)
    plain.data.materials.append(bpy.data.materials.new("plain"))
    textured.data.materials.append(checker_material(args.image))
    bpy.context.view_layer.update()
    build = {}
    for obj in (plain, textured):
        gpu_cache.clear_caches()
        start = time.perf_counter()
        offscreen.render_view(scene, objects=[obj])
        build[obj.name] = time.perf_counter() - start
    gpu_cache.clear_caches()
    offscreen.render_view(scene, objects=[plain])
    offscreen.render_view(scene, objects=[textured])
    frames = {"plain": [], "textured": []}
    for _ in range(args.frames):
        for obj in (plain, textured):
            start = time.perf_counter()
            offscreen.render_view(scene, objects=[obj])
            frames[obj.name].append(time.perf_counter() - start)
    p, t = (statistics.median(frames[k]) for k in ("plain", "textured"))
    print(f"{len(plain.data.polygons)} faces, {args.size}x{args.size} pixels, a {args.image}^2 image")
    print(f"frame: constant {1e3 * p:.1f} ms, image {1e3 * t:.1f} ms, ratio {t / p:.2f}")
    print(
        f"first draw (build + upload + frame): constant {build['plain']:.2f} s, image {build['textured']:.2f} s, "
        f"ratio {build['textured'] / build['plain']:.2f}"
    )


if __name__ == "__main__":
    main()
