"""Light split section of the accuracy report: every bundled HDRI, with and without the split.

Called by benchmarks/accuracy_report.py (run() measures, docs_section() writes the markdown). Per
scene of the report and per HDRI: Cycles' DIFFUSE/DIRECT vertex bake (E/pi, CYCLES samples), an
independent brute-force quadrature of the HDRI's texels (brute_force), and api.shade at orders 4
and 8 without and with the split (one order-8 bake: the order-4 light is zero-padded, i.e. the
first 16 coefficients of the same transfer). Cycles and brute-force references are cached in the
JSON (cache_key), so a re-run of the PRT side or of the docs does not bake them again.
"""

import base64
import math
import os
import time
import zlib
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from prt_addon.core.sh.resample import LUMINANCE as LUMA

HDRIS = ["city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset"]
ORDERS = [4, 8]
TARGET = {4: 0.05, 8: 0.025}
UNCERTAINTY_FACTOR = 1.25
CYCLES = 1024  # samples of the Cycles reference
PRT_SAMPLES = 2048  # Fibonacci directions of the order-8 bake (MC error far below the band limit)
COARSE = (128, 256)  # (H, W) of the downsampled sky in the brute force
COARSE_CHECK = (64, 128)  # a coarser sky: the difference measures the quadrature's own error
BRIGHT = 4096  # texels with the most power (luminance x solid angle) traced at full resolution
SWEEP_HDRIS = ["courtyard"]  # no compact source: what a lower threshold or more lights would give
SWEEP = [(0.0, 4), (8.0, 4), (5.0, 4), (5.0, 8), (3.0, 4), (3.0, 8), (2.0, 8)]  # (threshold, max lights)
PICTURE = ("suzanne", "sunrise")
PICTURE_SIZE = (480, 300)
IMAGES_DIR = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "docs", "images")  # --docs


def rel_err(y, ref):
    return float(np.sqrt(np.mean((y - ref) ** 2)) / np.sqrt(np.mean(ref**2)))


def pack(values):
    """float32 array -> compact JSON string (zlib + base64)."""
    data = np.ascontiguousarray(values, dtype=np.float32)
    return {"shape": list(data.shape), "data": base64.b64encode(zlib.compress(data.tobytes(), 9)).decode()}


def unpack(packed):
    raw = zlib.decompress(base64.b64decode(packed["data"]))
    return np.frombuffer(raw, dtype=np.float32).reshape(packed["shape"]).astype(np.float64)


def cache_key(kind, scene, hdri, vertices, setting):
    return f"{kind}/{scene}/{hdri}/{sum(vertices)}/{setting}"


# --- the brute-force reference -----------------------------------------------------------------


def hdri_pixels(bpy, name):
    """(H, W, 3) float64 linear RGB of a bundled HDRI, row 0 the nadir (Image.pixels order)."""
    folder = bpy.utils.system_resource("DATAFILES", path="studiolights/world")
    img = bpy.data.images.load(os.path.join(folder, f"{name}.exr"), check_existing=True)
    width, height = img.size
    px = np.empty(width * height * img.channels, np.float32)
    img.pixels.foreach_get(px)
    rgb = px.reshape(height, width, img.channels)[:, :, :3].astype(np.float64)
    rgb[~np.isfinite(rgb)] = 0.0
    return np.maximum(rgb, 0.0)


def quadrature_nodes(rgb, coarse, bright=BRIGHT):
    """(directions (K, 3), radiance x solid angle (K, 3)) of the image as point sources.

    The `bright` texels with the most luminance power are kept at full resolution (one node at
    each texel's centre); every other texel is summed into blocks of a coarse (H, W) grid (power
    conserved, node at the block's power-weighted mean direction). Texel solid angles are exact.
    """
    from prt_addon.core.sh.projection import pixel_directions, pixel_solid_angles

    height, width, _ = rgb.shape
    solid = pixel_solid_angles(height, width)[:, None]
    dirs = pixel_directions(height, width)
    power = rgb * solid[:, :, None]  # radiance x solid angle per texel, RGB
    lum = power @ LUMA
    flat = np.argsort(lum.ravel())[-bright:]
    keep = np.zeros(height * width, bool)
    keep[flat] = True
    keep = keep.reshape(height, width)
    rest = np.where(keep[:, :, None], 0.0, power)
    ch, cw = coarse
    by, bx = height // ch, width // cw
    block = rest.reshape(ch, by, cw, bx, 3).sum(axis=(1, 3))
    weight = (rest @ LUMA + 1e-30 * solid)[:, :, None]  # power-weighted direction (solid angle if dark)
    mean_dir = (dirs * weight).reshape(ch, by, cw, bx, 3).sum(axis=(1, 3))
    mean_dir /= np.linalg.norm(mean_dir, axis=-1, keepdims=True)
    d = np.concatenate([dirs[keep], mean_dir.reshape(-1, 3)])
    p = np.concatenate([power[keep], block.reshape(-1, 3)])
    nonzero = np.any(p > 0.0, axis=1)
    return d[nonzero], p[nonzero]


def ray_origins(bpy, objs):
    """World positions, unit normals, ray origins (the bake's offset along the normal and into
    the point's own surface, core.transfer.contact) and an Embree occluder of the whole scene."""
    from prt_addon.blender.scene import mesh_read, parts as scene_parts
    from prt_addon.core.trace import raytrace
    from prt_addon.core.transfer import mesh as core_mesh
    from prt_addon.core.transfer.contact import inward_tangents

    pos, nrm, org, verts, tris = [], [], [], [], []
    base = 0
    for obj in objs:
        m4 = core_mesh.matrix_to_numpy(obj.matrix_world)
        pts = mesh_read.bake_points(obj.data, m4)
        v = core_mesh.transform_points(m4, mesh_read.read_positions(obj.data))
        t = mesh_read.read_triangles(obj.data)
        diag = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
        off = max(scene_parts.OFFSET_REL * diag, scene_parts.OFFSET_ULP * float(np.abs(v).max()))
        n = pts.normals / np.linalg.norm(pts.normals, axis=1, keepdims=True)
        lift = n + inward_tangents(pts.positions, n, v, t, pts.vertex)
        pos.append(pts.positions)
        nrm.append(n)
        org.append(pts.positions + off * lift)
        verts.append(v)
        tris.append(t + base)
        base += len(v)
    occ = raytrace.EmbreeOccluder(np.concatenate(verts), np.concatenate(tris))
    return np.concatenate(pos), np.concatenate(nrm), np.concatenate(org), occ


def brute_force(points, nodes, chunk=48):
    """(P, 3) E/pi: sum over nodes of power x max(0, n . d) / pi x V, V traced with Embree from
    each point's ray origin (one ray per node above the point's tangent plane), on 2 threads."""
    _pos, nrm, org, occ = points
    d, p = nodes
    d32 = d.astype(np.float32)
    out = np.zeros((len(nrm), 3))

    def work(start):
        n = nrm[start : start + chunk]
        cos = n @ d.T
        which, k = np.nonzero(cos > 0.0)
        o = org[start : start + chunk][which].astype(np.float32)
        free = ~np.asarray(occ.occluded(o, d32[k]), dtype=bool)
        w = np.zeros(cos.shape)
        w[which[free], k[free]] = cos[which[free], k[free]]
        out[start : start + chunk] = w @ p / math.pi

    with ThreadPoolExecutor(2) as pool:
        list(pool.map(work, range(0, len(nrm), chunk)))
    return out


# --- the run -----------------------------------------------------------------------------------


def run(bpy, cfg, cache, log):
    """Measure the split section; cache holds packed references of an earlier run (updated)."""
    import accuracy_scenes as acc_scenes
    import accuracy_split_parts

    from prt_addon import api

    out = {"hdris": cfg.get("split_hdris", HDRIS), "orders": ORDERS, "cycles_samples": cfg.get("split_cycles", CYCLES)}
    out.update(prt_samples=PRT_SAMPLES, coarse=COARSE, coarse_check=COARSE_CHECK, bright=BRIGHT, scenes={})
    for scene_name in cfg["scenes"]:
        objs = acc_scenes.build_scene(bpy, scene_name)
        scene = bpy.context.scene
        nverts = [len(o.data.vertices) for o in objs]
        t0 = time.perf_counter()
        api.bake(objs, order=max(ORDERS), samples=PRT_SAMPLES, seed=0)
        res = out["scenes"][scene_name] = {"vertices": nverts, "bake_seconds": time.perf_counter() - t0, "rows": {}}
        points = ray_origins(bpy, objs)
        for hdri in out["hdris"]:
            acc_scenes.set_world(bpy, scene, hdri)
            row = res["rows"][hdri] = {}
            key = cache_key("cycles", scene_name, hdri, nverts, out["cycles_samples"])
            if key not in cache:
                secs, ref = acc_scenes.cycles_bake(bpy, scene, objs, out["cycles_samples"], seed=1)
                cache[key] = dict(pack(ref), seconds=secs)
            cyc = unpack(cache[key])
            row["cycles_seconds"] = cache[key]["seconds"]
            rgb = None
            for coarse, name in ((COARSE, "brute"), (COARSE_CHECK, "brute_check")):
                key = cache_key(name, scene_name, hdri, nverts, f"{coarse[0]}x{coarse[1]}+{BRIGHT}")
                if key not in cache:
                    rgb = hdri_pixels(bpy, hdri) if rgb is None else rgb
                    t1 = time.perf_counter()
                    nodes = quadrature_nodes(rgb, coarse)
                    cache[key] = dict(pack(brute_force(points, nodes)), seconds=time.perf_counter() - t1)
                    cache[key]["nodes"] = len(nodes[0])
                row[name + "_seconds"] = cache[key]["seconds"]
                row[name + "_nodes"] = cache[key]["nodes"]
            brute = unpack(cache[cache_key("brute", scene_name, hdri, nverts, f"{COARSE[0]}x{COARSE[1]}+{BRIGHT}")])
            check = unpack(
                cache[
                    cache_key("brute_check", scene_name, hdri, nverts, f"{COARSE_CHECK[0]}x{COARSE_CHECK[1]}+{BRIGHT}")
                ]
            )
            cy, by = cyc @ LUMA, brute @ LUMA
            row["cycles_vs_brute"] = rel_err(cy, by)
            row["brute_vs_check"] = rel_err(check @ LUMA, by)
            row["prt"] = {}
            for split in (False, True):
                for n in ORDERS:
                    api.project_world(scene, n, split_lights=split)
                    t1 = time.perf_counter()
                    y = np.concatenate([api.shade(o, scene) for o in objs]) @ LUMA
                    row["prt"][f"{n}{'s' if split else ''}"] = {
                        "cycles": rel_err(y, cy),
                        "brute": rel_err(y, by),
                        "shade_seconds": time.perf_counter() - t1,
                    }
            if hdri in SWEEP_HDRIS:
                row["sweep"] = sweep(scene, objs, cy, by)
                rgb = hdri_pixels(bpy, hdri) if rgb is None else rgb
                row["parts"] = accuracy_split_parts.parts(
                    scene, objs, points, rgb, by, ORDERS, brute_force, quadrature_nodes, COARSE
                )
            rgb = hdri_pixels(bpy, hdri) if rgb is None else rgb
            row["rule"] = accuracy_split_parts.rule(scene, objs, rgb, cy, ORDERS)
            api.project_world(scene, max(ORDERS), split_lights=True)
            w = scene.prt_world
            row["lights"] = {
                "count": int(w.light_count),
                "share": float(w.light_share),
                "elevation_deg": math.degrees(float(w.strongest_elevation)) if w.light_count else None,
                "angles_deg": [math.degrees(lt["angle"]) for lt in api.world_lights(scene)],
            }
            log(
                "split",
                scene_name,
                hdri,
                f"cycles~brute {100 * row['cycles_vs_brute']:.2f} %",
                {k: round(100 * v["cycles"], 2) for k, v in row["prt"].items()},
            )
        if scene_name == PICTURE[0]:
            out["pictures"] = pictures(bpy, scene, objs, PICTURE[1], cache, nverts, out["cycles_samples"])
    return out


def sweep(scene, objs, cy, by):
    """Errors at each (threshold, max lights) of SWEEP (threshold 0: automatic), both orders, with
    the lights shaded by their samples and (key "discs") as uniform discs of the moment radius."""
    import dataclasses

    import accuracy_split_parts

    from prt_addon import api
    from prt_addon.blender.world import light_split

    rows = []
    for threshold, max_lights in SWEEP:
        row = {"threshold": threshold, "max_lights": max_lights}
        for n in ORDERS:
            api.project_world(scene, n, split_lights=True, threshold=threshold, max_lights=max_lights)
            y = np.concatenate([api.shade(o, scene) for o in objs]) @ LUMA
            discs = [dataclasses.replace(lt, samples=None, weights=None) for lt in light_split.stored(scene)]
            yd = accuracy_split_parts.shade_luminance(objs, scene, lights=discs)
            row[str(n)] = {"cycles": rel_err(y, cy), "brute": rel_err(y, by)}
            row[str(n)]["discs"] = {"cycles": rel_err(yd, cy), "brute": rel_err(yd, by)}
        row.update(count=int(scene.prt_world.light_count), share=float(scene.prt_world.light_share))
        row["angles_deg"] = [math.degrees(lt["angle"]) for lt in api.world_lights(scene)]
        rows.append(row)
    return rows


# --- pictures ----------------------------------------------------------------------------------


def _camera(bpy, scene, sun):
    """A camera 110 degrees round from the sun's azimuth (the shadow runs across the picture), on
    the side nearer the shape's front (-Y), looking down at the shape's middle."""
    from mathutils import Vector

    azimuth = math.radians(-70.0)
    if sun is not None:
        sides = [math.atan2(sun[1], sun[0]) + math.radians(a) for a in (110.0, -110.0)]
        azimuth = max(sides, key=lambda a: -math.sin(a))  # the one nearer -Y
    eye = Vector((7.5 * math.cos(azimuth), 7.5 * math.sin(azimuth), 4.0))
    cam = bpy.data.objects.new("report_camera", bpy.data.cameras.new("report_camera"))
    scene.collection.objects.link(cam)
    cam.location = eye
    cam.rotation_euler = (Vector((0.0, 0.0, 0.5)) - eye).to_track_quat("-Z", "Y").to_euler()
    cam.data.lens = 40.0
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = PICTURE_SIZE
    scene.render.resolution_percentage = 100
    return cam


def rasterise(bpy, scene, objs, colours):
    """(H, W, 4) image of per-vertex linear colours, Gouraud-interpolated by the gpu module's
    builtin SMOOTH_COLOR shader from the scene camera (the same rasteriser for every picture)."""
    import gpu
    from gpu_extras.batch import batch_for_shader

    from prt_addon.blender.display import offscreen
    from prt_addon.blender.scene import mesh_read

    offscreen.ensure_gpu()
    width, height = PICTURE_SIZE
    view, proj = offscreen.camera_matrices(scene, width, height)
    shader = gpu.shader.from_builtin("SMOOTH_COLOR")
    fbo = gpu.types.GPUOffScreen(width, height, format="RGBA32F")
    start = 0
    try:
        with fbo.bind():
            fb = gpu.state.active_framebuffer_get()
            fb.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
            gpu.state.depth_test_set("LESS_EQUAL")
            gpu.state.depth_mask_set(True)
            from mathutils import Matrix

            gpu.matrix.load_matrix(Matrix(view.tolist()))
            gpu.matrix.load_projection_matrix(Matrix(proj.tolist()))
            for obj in objs:
                m4 = np.array(obj.matrix_world)
                v = mesh_read.read_positions(obj.data) @ m4[:3, :3].T + m4[:3, 3]
                c = colours[start : start + len(v)]
                start += len(v)
                rgba = np.concatenate([c, np.ones((len(c), 1))], axis=1).astype(np.float32)
                batch = batch_for_shader(
                    shader,
                    "TRIS",
                    {"pos": v.astype(np.float32), "color": rgba},
                    indices=mesh_read.read_triangles(obj.data).astype(np.int32),
                )
                batch.draw(shader)
            gpu.state.depth_test_set("NONE")
            buf = fb.read_color(0, 0, width, height, 4, 0, "FLOAT")
            image = np.asarray(buf).T.reshape(height, width, 4).copy()
    finally:
        fbo.free()
    return image[::-1].copy()


def pictures(bpy, scene, objs, hdri, cache, nverts, samples):
    """PNGs under docs/images: Cycles, PRT order 8 without and with the split (per-vertex values,
    one rasteriser), and PRT with the split as the viewport draws it (api.render_view)."""
    from prt_addon import api

    img_dir = IMAGES_DIR
    rep_world = bpy.data.worlds[hdri]
    scene.world = rep_world
    api.project_world(scene, 8, split_lights=True)
    sun = api.world_lights(scene)[0]["direction"] if api.world_lights(scene) else None
    _camera(bpy, scene, sun)
    scene.view_settings.view_transform = "AgX"
    cyc = unpack(cache[cache_key("cycles", PICTURE[0], hdri, nverts, samples)])
    scene.view_settings.exposure = float(-math.log2(4.0 * np.mean(cyc @ LUMA)))  # mean to 1/4
    images = {"cycles": rasterise(bpy, scene, objs, cyc)}
    api.project_world(scene, 8, split_lights=False)
    images["prt"] = rasterise(bpy, scene, objs, np.concatenate([api.shade(o, scene) for o in objs]))
    api.project_world(scene, 8, split_lights=True)
    images["prt_split"] = rasterise(bpy, scene, objs, np.concatenate([api.shade(o, scene) for o in objs]))
    images["prt_split_view"] = api.render_view(scene, *PICTURE_SIZE)
    names = {}
    for key, image in images.items():
        name = f"accuracy_split_{key}.png"
        api.save_png(image, os.path.join(img_dir, name), scene, background=(0.05, 0.05, 0.05))
        names[key] = name
    return {"scene": PICTURE[0], "hdri": hdri, "order": 8, "files": names, "exposure": scene.view_settings.exposure}
