"""Display benchmark: per-frame draw cost of the PRT shader against a flat-shaded draw
of the same batch, with and without the display transform, the cost of a lighting-rotation
update per order, and the time to build a display-transform table.

    .venv/bin/python benchmarks/bench_display.py [--triangles 1000000] [--frames 15] [--size 512]

Both draws use the same vertex/index buffers (the flat shader reads only the position) into the
same RGBA32F offscreen with depth test; they are interleaved frame by frame and each frame is
synchronised by reading one pixel back. Ratios are measured side by side in one run; absolute
times are for this machine only (llvmpipe, software OpenGL, on 2 cores).
"""

import argparse
import math
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import bpy
import gpu
import numpy as np

import prt_addon
from prt_addon.blender.display import colour, draw as display_draw, gpu_cache, offscreen, shader as display_shader
from prt_addon.blender.scene import lighting, storage
from prt_addon.core.sh import analytic, basis as sh


def flat_shader():
    info = gpu.types.GPUShaderCreateInfo()
    info.push_constant("MAT4", "mvp")
    info.push_constant("VEC4", "tint")
    info.vertex_in(0, "VEC3", "prt_pos")
    info.fragment_out(0, "VEC4", "FragColor")
    info.vertex_source("void main() { gl_Position = mvp * vec4(prt_pos, 1.0); }")
    info.fragment_source("void main() { FragColor = tint; }")
    return gpu.shader.create_from_info(info)


def make_sphere(triangles):
    import bmesh

    segments = int(round(math.sqrt(triangles)))
    rings = max(3, triangles // (2 * segments) + 1)
    mesh = bpy.data.meshes.new("Bench")
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=segments, v_segments=rings, radius=1.0)
    bm.to_mesh(mesh)
    bm.free()
    mesh.shade_smooth()
    obj = bpy.data.objects.new("Bench", mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def write_transfer(obj, order):
    """Unshadowed transfer (clamped cosine about the normal), written per docs/storage.md."""
    mesh = obj.data
    for name in [a.name for a in mesh.attributes if a.name.startswith(storage.PREFIX)]:
        mesh.attributes.remove(mesh.attributes[name])
    n = len(mesh.vertices)
    co = np.empty(n * 3, dtype=np.float32)
    mesh.attributes["position"].data.foreach_get("vector", co)
    normals = co.reshape(-1, 3).astype(np.float64)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    n2 = order * order
    count = storage.attribute_count(order)
    zonal = analytic.clamped_cosine_zonal(order)
    bands = sh.band_of_index(order)
    scale = np.sqrt(4 * np.pi / (2 * bands + 1)) * zonal[bands]
    padded = np.zeros((n, 4 * count), dtype=np.float32)
    for s in range(0, n, 200000):
        padded[s : s + 200000, :n2] = sh.sh_basis(normals[s : s + 200000], order) * scale
    names = [storage.attribute_name(k) for k in range(count)]
    for name in names:
        mesh.color_attributes.new(name, "FLOAT_COLOR", "POINT")
    for k, name in enumerate(names):
        mesh.attributes[name].data.foreach_set("color", np.ascontiguousarray(padded[:, 4 * k : 4 * k + 4]).ravel())
    mesh["prt_bake"] = {"order": order, "count": count, "domain": "POINT"}


def time_frames(scene, obj, mvp, entry, prt_shader, flat, frames, size, lut):
    off = gpu.types.GPUOffScreen(size, size, format="RGBA32F")
    prt_times, flat_times, display_times = [], [], []
    with off.bind():
        fb = gpu.state.active_framebuffer_get()
        gpu.state.depth_test_set("LESS_EQUAL")
        gpu.state.depth_mask_set(True)

        def frame(kind):
            fb.clear(color=(0, 0, 0, 0), depth=1.0)
            t0 = time.perf_counter()
            if kind == "prt":
                display_draw.draw_objects(scene, mvp, [obj])
            elif kind == "display":
                display_draw.draw_objects(scene, mvp, [obj], display_lut=lut)
            else:
                flat.bind()
                flat.uniform_float("mvp", mvp @ obj.matrix_world)
                flat.uniform_float("tint", (0.8, 0.8, 0.8, 1.0))
                for _mat, batch in entry.batches:
                    batch.draw(flat)
            fb.read_color(size // 2, size // 2, 1, 1, 4, 0, "FLOAT")  # wait for the GPU
            return time.perf_counter() - t0

        frame("prt"), frame("flat"), frame("display")  # warm up (upload, compile)
        for _ in range(frames):
            prt_times.append(frame("prt"))
            flat_times.append(frame("flat"))
            display_times.append(frame("display"))
        gpu.state.depth_test_set("NONE")
    off.free()
    return statistics.median(prt_times), statistics.median(flat_times), statistics.median(display_times)


def rotation_update_cost(order, repeats=50):
    """One lighting-rotation update: rotate the world light by the Mapping rotation, rotate it
    into an object's frame, pack std140 and upload the uniform buffer. No projection, no bake."""
    from prt_addon.core.sh import rotation

    light = analytic.cap_coeffs(order, (1.0, 0.0, 0.0), 0.3, radiance=(5.0, 4.0, 3.0))
    count = storage.attribute_count(order)
    ubo = gpu.types.GPUUniformBuf(display_shader.light_ubo_bytes(light, count))
    obj_matrix = np.eye(4)
    obj_matrix[:3, :3] = rotation.euler_xyz_matrix((0.3, 0.2, 0.1))
    times = []
    for i in range(repeats):
        euler = (0.0, 0.0, 0.01 * (i + 1))
        t0 = time.perf_counter()
        world = rotation.rotate(light, rotation.euler_xyz_matrix(euler).T)
        local = lighting.light_in_local_frame(world, obj_matrix, order)
        ubo.update(display_shader.light_ubo_bytes(local, count))
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--triangles", type=int, default=1_000_000)
    parser.add_argument("--frames", type=int, default=15)
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--orders", type=int, nargs="+", default=[3, 4, 7, 8])
    args = parser.parse_args()

    bpy.ops.wm.read_factory_settings(use_empty=True)
    prt_addon.register()
    assert offscreen.ensure_gpu()  # before building the large mesh
    scene = bpy.context.scene
    scene.prt_display.albedo_source = "WHITE"
    cam_data = bpy.data.cameras.new("Cam")
    cam = bpy.data.objects.new("Cam", cam_data)
    scene.collection.objects.link(cam)
    cam.location = (0.0, -4.0, 0.0)
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)
    scene.camera = cam

    obj = make_sphere(args.triangles)
    bpy.context.view_layer.update()
    view, proj = offscreen.camera_matrices(scene, args.size, args.size)
    import mathutils

    mvp = mathutils.Matrix((proj @ view).tolist())
    flat = flat_shader()
    print(f"renderer: {gpu.platform.renderer_get()}")
    obj.data.calc_loop_triangles()
    print(
        f"mesh: {len(obj.data.loop_triangles):,} triangles, {len(obj.data.vertices):,} vertices; "
        f"{args.size}x{args.size} offscreen, median of {args.frames} interleaved frames"
    )
    lut = colour.texture(scene, build=True)
    print("PRT+colour: the same PRT draw through the scene's display transform (colour.py)")
    print(
        f"{'order':>5} {'coeffs':>6} {'path':>8} {'flat ms':>9} {'PRT ms':>9} {'ratio':>6} "
        f"{'PRT+colour ms':>13} {'/ PRT':>6}"
    )
    for order in args.orders:
        gpu_cache.clear_caches()
        write_transfer(obj, order)
        lighting.set_light_override(scene, analytic.cap_coeffs(order, (1, 0, 0), 0.3, radiance=(5, 4, 3)))
        info, _ = storage.usable_bake(obj.data)
        entry = gpu_cache.get_mesh_entry(obj.data, info, "WHITE", "")
        prt_t, flat_t, display_t = time_frames(
            scene, obj, mvp, entry, display_shader.get_shader(info.count), flat, args.frames, args.size, lut
        )
        print(
            f"{order:>5} {order * order:>6} {display_shader.shader_mode(info.count):>8} "
            f"{flat_t * 1e3:>9.1f} {prt_t * 1e3:>9.1f} {prt_t / flat_t:>6.2f} "
            f"{display_t * 1e3:>13.1f} {display_t / prt_t:>6.2f}"
        )

    print()
    print("lighting-rotation update (world rotation + object frame + std140 pack + UBO upload)")
    print(f"{'order':>5} {'ms':>8}")
    for order in (2, 3, 4, 6, 8, 12, 16):
        print(f"{order:>5} {rotation_update_cost(order) * 1e3:>8.3f}")
    print()
    times = []
    for _ in range(5):
        start = time.perf_counter()
        colour.build_table(scene)
        times.append(time.perf_counter() - start)
    print(f"display-transform table ({colour.LUT_SIZE}^3, {scene.view_settings.view_transform}): ", end="")
    print(f"median {statistics.median(times) * 1e3:.0f} ms, min {min(times) * 1e3:.0f} ms of 5 builds")
    prt_addon.unregister()


if __name__ == "__main__":
    main()
