"""Main job: the bundled demo scene, projected, baked and shown through the PRT shader.

    bash scripts/demo.sh [--hdri forest] [--order 8] [--samples 256] [--output out]

1. Projects a bundled Blender HDRI into SH at several orders and prints the reconstruction error
   of the radiance and of unshadowed diffuse shading (against a brute-force sum over every pixel)
   with the projection time, and the RGB coefficients at order 3.
2. Builds the default scene (Suzanne, subdivided and smooth, on a ground plane, a camera, the HDRI
   as the world behind a Mapping node), runs Project World and Bake as a user would
   (prt.project_world, prt.bake_transfer), prints the bake report, renders the PRT view offscreen
   at lighting rotations of 0, 120 and 240 degrees about Z, and writes the PNGs and the .blend;
   compares the PRT shading with Cycles' per-vertex bake of the same scene.
3. Exports the scene to out/prt_demo.glb, and builds the web viewer with that file inside it,
   out/prt_viewer.html (scripts/build_web.sh; needs Node.js and npm).
It prints what a user came for first (what was baked, how long, how far from Cycles, where the
pictures are), then the projection detail.
"""

import argparse
import json
import os
import subprocess
import sys
import time
import warnings

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from prt_addon.core.sh import analytic, basis as sh, directions, projection
from prt_addon.core.sh.resample import LUMINANCE


def bundled_hdri_path(name):
    import bpy

    path = os.path.join(bpy.utils.system_resource("DATAFILES", path="studiolights/world"), f"{name}.exr")
    if not os.path.isfile(path):
        raise SystemExit(f"no bundled HDRI named {name!r} (try forest, city, courtyard, sunrise)")
    return path


def read_pixels(image):
    width, height = image.size
    pixels = np.empty(width * height * image.channels, np.float32)
    image.pixels.foreach_get(pixels)
    return pixels.reshape(height, width, image.channels)


def relative_rms(approx, exact, weights):
    return float(np.sqrt(np.sum(weights * (approx - exact) ** 2) / np.sum(weights * exact**2)))


def projection_table(pixels, orders):
    height, width = pixels.shape[:2]
    rgb = pixels[:, :, :3].astype(np.float64)
    dirs = projection.pixel_directions(height, width).reshape(-1, 3)
    weights = np.repeat(projection.pixel_solid_angles(height, width), width)
    image_lum = rgb.reshape(-1, 3) @ LUMINANCE
    normals = directions.fibonacci_directions(1024)
    # Brute-force diffuse truth: every pixel a small light of its solid angle.
    cosines = np.maximum(0.0, normals.astype(np.float32) @ dirs.T.astype(np.float32))
    truth = (cosines @ (rgb.reshape(-1, 3) * weights[:, None]).astype(np.float32)) @ LUMINANCE / np.pi
    print(f"{'order':>5} {'coeffs':>6} {'project ms':>10} {'radiance err':>12} {'diffuse err':>11}")
    coeffs_by_order = {}
    for order in orders:
        start = time.perf_counter()
        coeffs, report = projection.project_equirect(pixels, order)
        seconds = time.perf_counter() - start
        radiance_error = relative_rms(sh.evaluate(coeffs, dirs) @ LUMINANCE, image_lum, weights)
        diffuse = sh.evaluate(sh.convolve_zonal(coeffs, analytic.clamped_cosine_zonal(order)), normals) @ LUMINANCE
        diffuse_error = relative_rms(diffuse, truth, np.ones_like(diffuse))
        print(f"{order:>5} {order * order:>6} {seconds * 1e3:>10.1f} {radiance_error:>11.1%} {diffuse_error:>10.2%}")
        coeffs_by_order[order] = coeffs
    print(f"pixel check: {report.summary()}")
    print("(radiance err is the square root of the energy beyond the order, by Parseval: a sun keeps it")
    print(" high; diffuse err is what unshadowed diffuse shading sees)")
    return coeffs_by_order


def build_scene(hdri_path):
    """Suzanne (subdivided twice, smooth) on a 6x6 ground grid, a camera, the HDRI world."""
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_monkey_add(size=2.0, location=(0.0, 0.0, 0.75), rotation=(-0.35, 0.0, 0.5))
    suzanne = bpy.context.active_object
    suzanne.name = "Suzanne"
    modifier = suzanne.modifiers.new("Subdivision", "SUBSURF")
    modifier.levels = 2
    bpy.ops.object.modifier_apply(modifier=modifier.name)
    bpy.ops.object.shade_smooth()
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=60, y_subdivisions=60, size=6.0, location=(0.0, 0.0, 0.0))
    bpy.context.active_object.name = "Ground"

    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera)
    camera.location = (4.6, -5.4, 3.6)
    direction = -np.array(camera.location) + np.array([0.0, 0.0, 0.9])
    camera.rotation_euler = (
        np.arctan2(np.hypot(direction[0], direction[1]), -direction[2]),
        0.0,
        np.arctan2(direction[1], direction[0]) - np.pi / 2,
    )
    scene.camera = camera
    scene.render.resolution_x, scene.render.resolution_y = 480, 360

    world = bpy.data.worlds.new("HDRI")
    with warnings.catch_warnings():  # Blender 5.0 deprecates use_nodes; 4.2 needs it
        warnings.simplefilter("ignore", DeprecationWarning)
        world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    environment = nodes.new("ShaderNodeTexEnvironment")
    environment.image = bpy.data.images.load(hdri_path, check_existing=True)
    coords = nodes.new("ShaderNodeTexCoord")
    mapping = nodes.new("ShaderNodeMapping")
    links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], environment.inputs["Vector"])
    links.new(environment.outputs["Color"], nodes["Background"].inputs["Color"])
    scene.world = world
    return scene


def cycles_direct(bpy, scene, obj, samples):
    """Cycles' per-vertex E/pi of obj (white albedo, direct light): the independent reference.
    Baked into a temporary colour attribute that is removed again."""
    mesh = obj.data
    active = mesh.color_attributes.active_color_name
    attribute = mesh.color_attributes.new("cycles_reference", "FLOAT_COLOR", "POINT")
    mesh.color_attributes.active_color = attribute
    scene.render.engine = "CYCLES"
    scene.cycles.samples = samples
    scene.cycles.device = "CPU"
    for other in scene.objects:
        other.select_set(other == obj)
    bpy.context.view_layer.objects.active = obj
    bpy.ops.object.bake(type="DIFFUSE", pass_filter={"DIRECT"}, target="VERTEX_COLORS", use_clear=True)
    values = np.empty(len(mesh.vertices) * 4, np.float32)
    mesh.color_attributes["cycles_reference"].data.foreach_get("color", values)
    mesh.color_attributes.remove(mesh.color_attributes["cycles_reference"])
    if active in mesh.color_attributes:
        mesh.color_attributes.active_color_name = active
    return values.reshape(-1, 4)[:, :3].astype(np.float64)


def relative_rmse(ours, theirs):
    """Relative RMSE of luminance over all vertices (the accuracy report's measure)."""
    a, b = ours @ LUMINANCE, theirs @ LUMINANCE
    return float(np.sqrt(np.mean((a - b) ** 2)) / np.sqrt(np.mean(b**2)))


def shown(path):
    """A path as a user types it: relative to the repository when inside it."""
    relative = os.path.relpath(path, ROOT)
    return path if relative.startswith("..") else relative


def print_summary(args, summary):
    status, report = summary["bake"]
    points = report["points"]
    print(f"PRT Lighting demo: {args.hdri}.exr lighting Suzanne on a ground plane")
    print(
        f"  Baked {len(report['objects'])} objects ({points:,} points) at order {report['order']} in "
        f"{report['seconds']:.2f} s: {report['rays_traced'] / 1e6:.1f} M rays, about "
        f"{100.0 * report['error_estimate_relative']:.1f} % noise ({report['backend']}, {status.lower()})"
    )
    error, seconds, samples = summary["cycles"]
    print(
        f"  Against Cycles ({samples} samples, {seconds:.1f} s): {100.0 * error:.1f} % relative RMSE of "
        "luminance per vertex (the SH band limit and Cycles' own noise; docs/accuracy.md)"
    )
    paths, seconds = summary["renders"]
    print(f"  Pictures ({len(paths)} lighting rotations, {seconds:.2f} s): " + ", ".join(shown(p) for p in paths))
    print(f"  Blender file: {shown(summary['blend'])} (open it and rotate the HDRI in the PRT tab)")
    print(f"  For other engines: {shown(summary['glb'])} (glTF with the transfer and the lighting, docs/export.md)")
    viewer, problem = summary["viewer"]
    if viewer:
        print(f"  Web viewer: {shown(viewer)} (open it in a browser, drag to turn the lighting)")
    else:
        print(f"  Web viewer not built: {problem}")
    print(f"  World projected in {summary['project'][1] * 1e3:.0f} ms ({summary['project'][0].lower()})")


def build_viewer(glb, page):
    """(page, None) after building the web viewer with the .glb embedded, or (None, why not)."""
    try:
        run = subprocess.run(
            ["bash", os.path.join(ROOT, "scripts", "build_web.sh"), "--out", page, "--glb", glb],
            capture_output=True,
            text=True,
            timeout=900,
        )
    except (OSError, subprocess.TimeoutExpired) as error:
        return None, str(error)
    if run.returncode != 0:
        return None, (run.stderr.strip().splitlines() or ["scripts/build_web.sh failed"])[-1]
    return page, None


def run_scene(args, summary):
    import bpy

    import prt_addon
    from prt_addon import api
    from prt_addon.blender.display import offscreen

    offscreen.ensure_gpu()  # before building large meshes: it renders a scene
    try:
        prt_addon.register()
        scene = build_scene(bundled_hdri_path(args.hdri))

        scene.prt_world.order = args.order
        summary["project"] = (bpy.ops.prt.project_world().pop(), scene.prt_world.seconds)

        for obj in scene.objects:
            obj.select_set(obj.type == "MESH")
        bpy.context.view_layer.objects.active = scene.objects["Suzanne"]
        settings = scene.prt_bake
        settings.order, settings.samples, settings.shadows = args.order, args.samples, True
        settings.bounces = 0  # compared with Cycles' direct light below (the panel's default bakes 4 bounces)
        result = bpy.ops.prt.bake_transfer()
        report = json.loads(settings.last_report)
        summary["bake"] = (result.pop(), report)
        os.makedirs(args.output, exist_ok=True)
        meshes = [scene.objects["Suzanne"], scene.objects["Ground"]]
        ours = np.concatenate([api.shade(obj) for obj in meshes])
        start = time.perf_counter()
        theirs = np.concatenate([cycles_direct(bpy, scene, obj, args.cycles_samples) for obj in meshes])
        summary["cycles"] = (relative_rmse(ours, theirs), time.perf_counter() - start, args.cycles_samples)
        pattern = os.path.join(args.output, "prt_rotation_{:03d}.png")
        start = time.perf_counter()
        paths = offscreen.render_rotations(scene, [0, 120, 240], pattern)
        summary["renders"] = (paths, time.perf_counter() - start)
        blend = os.path.join(args.output, "prt_demo.blend")
        bpy.ops.wm.save_as_mainfile(filepath=blend)
        summary["blend"] = blend
        summary["glb"] = api.export_gltf(os.path.join(args.output, "prt_demo.glb"), scene=scene)
        summary["viewer"] = build_viewer(summary["glb"], os.path.join(args.output, "prt_viewer.html"))
    finally:
        # bpy 4.x as a module frees classes still registered at exit after Python has shut down
        # and segfaults: unregister while Python runs (full Blender does this itself).
        prt_addon.unregister()


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hdri", default="forest", help="bundled studio-light HDRI name")
    parser.add_argument("--orders", default="2,3,4,6,8,12,16", help="orders of the projection table")
    parser.add_argument("--order", type=int, default=8, help="order of the demo scene's bake")
    parser.add_argument("--samples", type=int, default=256, help="directions of the demo scene's bake")
    parser.add_argument("--cycles-samples", type=int, default=64, help="samples of the Cycles reference bake")
    parser.add_argument("--output", default=os.path.join(ROOT, "out"), help="folder for the PNGs and the .blend")
    args = parser.parse_args(argv)

    import bpy

    summary = {}
    run_scene(args, summary)
    print_summary(args, summary)
    print("\nDetail: the projection of the HDRI by order (against a brute-force sum over every pixel)\n")
    path = bundled_hdri_path(args.hdri)
    image = bpy.data.images.load(path, check_existing=True)
    pixels = read_pixels(image)
    print(
        f"HDRI {os.path.basename(path)}: {image.size[0]}x{image.size[1]}, peak {pixels[..., :3].max():.4g}, "
        f"mean {pixels[..., :3].mean():.4g}\n"
    )
    coeffs = projection_table(pixels, [int(o) for o in args.orders.split(",")])
    if 3 in coeffs:
        print("\nRGB coefficients at order 3 (index i = l(l+1)+m, no Condon-Shortley phase, Z up):")
        for i, (r, g, b) in enumerate(coeffs[3]):
            l = int(np.sqrt(i))
            print(f"  i={i} l={l} m={i - l * (l + 1):>2}: {r:10.5f} {g:10.5f} {b:10.5f}")
    return 0


def exit_now(status):
    """Exit with `status`. The bpy 4.2 module crashes at interpreter exit once the glTF exporter
    has run (its SpaceType destructors call into the finalised Python; 4.3+ exit cleanly), so
    on 4.2 the demo leaves before those destructors, after flushing its output."""
    bpy = sys.modules.get("bpy")
    if bpy is not None and tuple(bpy.app.version[:2]) < (4, 3) and "io_scene_gltf2" in sys.modules:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(status)
    sys.exit(status)


if __name__ == "__main__":
    exit_now(main())
