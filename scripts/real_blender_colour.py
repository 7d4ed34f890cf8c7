"""The colour part of the real-Blender check: the overlay on screen and Blender's own view transform.

Imported by real_blender_check.py inside a real Blender window, after the display is on. It
compares (1) the 3D View's pixels (screen.screenshot_area) with the same view drawn offscreen
through draw_objects and the display transform, encoded as render_view(display=True) does,
and (2) render_view(display=True) with the linear render_view pushed through Image.save_render
for every view transform, exposure 0.7 and gamma 1.3; and saves the PRT view beside a Cycles
render (direct light only) of the same camera under the scene's view transform; and checks that
building a table (a temporary scene and images) leaves a saved file unmodified.
"""

import importlib
import os
import subprocess

import bpy

CHECK = "the overlay shows the view transform as Blender applies it"
SUPPORTED_LIMIT = 2.0  # mean |difference| in 1/255 over the drawn pixels
APPROXIMATE = ("False Color",)  # bands: a table blurs their edges (docs/display.md)
SIZE = (320, 240)
_selected = []  # names of the objects selected before prepare(), selected again after run()
_markers = []  # whether the light markers were on before prepare(), restored at the end


def _read_png(path, drop=True):
    """(H, W, 4) float32 stored values of a PNG, row 0 at the bottom."""
    import numpy as np

    image = bpy.data.images.load(path)
    image.colorspace_settings.name = "Non-Color"
    w, h = image.size
    pixels = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(pixels)
    if drop:
        bpy.data.images.remove(image)
    return pixels.reshape(h, w, 4)


def _write_png(rgba, path):
    """Write display-referred (H, W, 4) values, row 0 at the bottom, as they are (no transform)."""
    import numpy as np

    h, w = rgba.shape[:2]
    image = bpy.data.images.new("prt_colour_png", w, h, alpha=True)
    image.pixels.foreach_set(np.ascontiguousarray(rgba, dtype=np.float32).ravel())
    image.filepath_raw, image.file_format = path, "PNG"
    image.save()
    bpy.data.images.remove(image)


def _erode(mask, steps):
    import numpy as np

    for _ in range(steps):
        mask = mask & np.roll(mask, 1, 0) & np.roll(mask, -1, 0) & np.roll(mask, 1, 1) & np.roll(mask, -1, 1)
    return mask


def screen_against_offscreen(out, mod, ctx, folder):
    """The 3D View's pixels where PRT draws, against the same view drawn offscreen."""
    import gpu
    import numpy as np

    colour, draw, lighting = mod("blender.display.colour"), mod("blender.display.draw"), mod("blender.scene.lighting")
    scene, area, region, window = bpy.context.scene, ctx["area"], ctx["region"], ctx["window"]
    path = os.path.join(folder, "screen.png")  # the X screen as the user sees it (Blender's own
    subprocess.run(["import", "-display", os.environ.get("DISPLAY", ":99"), "-window", "root", path], check=True)
    shot = _read_png(path)  # screenshot_area read back black under Xvfb)
    out["screen_size"], out["window_size"] = [shot.shape[1], shot.shape[0]], [window.width, window.height]
    shot = shot[shot.shape[0] - window.height :, : window.width]  # (the window at the top left: no window manager)
    space = area.spaces.active
    objects = draw.baked_objects(scene, bpy.context.view_layer, space)
    w, h = region.width, region.height
    off = gpu.types.GPUOffScreen(w, h, format="RGBA32F")
    with off.bind():
        fb = gpu.state.active_framebuffer_get()
        fb.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
        gpu.state.depth_test_set("LESS_EQUAL")
        gpu.state.depth_mask_set(True)
        draw.draw_objects(
            scene,
            space.region_3d.perspective_matrix,
            objects,
            scale=lighting.exposure_scale(scene),
            depsgraph=bpy.context.evaluated_depsgraph_get(),
            display_lut=colour.texture(scene),
        )
        gpu.state.depth_test_set("NONE")
        image = np.asarray(fb.read_color(0, 0, w, h, 4, 0, "FLOAT")).T.reshape(h, w, 4).copy()
    off.free()
    screen = shot[region.y : region.y + h, region.x : region.x + w, :3]  # (window coordinates, rows from the bottom)
    mask = _erode(image[..., 3] > 0, 3)
    sidebar = [r for r in area.regions if r.type == "UI"]
    if sidebar:  # (the sidebar and the navigation gizmo sit over the view's right side)
        mask[:, max(0, sidebar[0].x - region.x - 120) :] = False
    mask[h - 80 :, :] = False
    ours = colour.encode_display(image[..., :3])
    diff = np.abs(ours - screen)[mask] * 255.0
    signed = (screen - ours)[mask] * 255.0
    bins = np.minimum((ours[mask] * 10).astype(int), 9)  # (screen - ours) by our value, tenths
    out["screen_minus_offscreen_by_value"] = {
        f"{b / 10:.1f}": round(float(signed[bins == b].mean()), 3) for b in range(10) if (bins == b).any()
    }
    out["screen_minus_offscreen_mean_rgb"] = signed.reshape(-1, 3).mean(axis=0).round(3).tolist()
    np.savez_compressed(os.path.join(folder, "screen_pairs.npz"), ours=ours[mask], screen=screen[mask])
    out["screen_pixels_compared"] = int(mask.sum())
    out["screen_vs_offscreen_mean"] = float(diff.mean()) if diff.size else None
    out["screen_vs_offscreen_p99"] = float(np.percentile(diff, 99)) if diff.size else None
    out["screen_mean_rgb"] = screen[mask].mean(axis=0).round(4).tolist() if diff.size else None


def add_camera(scene):
    from mathutils import Vector

    camera = bpy.data.objects.new("PRT Check Camera", bpy.data.cameras.new("PRT Check Camera"))
    scene.collection.objects.link(camera)
    camera.location = (5.0, -5.0, 3.6)
    camera.rotation_euler = (Vector((0.0, 0.0, 0.7)) - camera.location).to_track_quat("-Z", "Y").to_euler()
    scene.camera = camera
    scene.render.resolution_x, scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100


def transforms_against_save_render(out, mod, folder):
    """render_view(display=True) against save_render of the linear render, every view transform."""
    import numpy as np

    api = importlib.import_module(mod("blender").__name__.rsplit(".", 1)[0] + ".api")
    scene = bpy.context.scene
    view = scene.view_settings
    saved = (view.view_transform, view.look, view.exposure, view.gamma)
    try:
        view.view_transform = "__none__"
    except TypeError as exc:
        text = str(exc)
        names = [n.strip().strip("'\"") for n in text[text.rindex("(") + 1 : text.rindex(")")].split(",")]
    rows = {}
    try:
        for name in names:
            view.view_transform, view.look, view.exposure, view.gamma = name, "None", 0.7, 1.3
            linear = api.render_view(scene)
            shown = api.render_view(scene, display=True)
            path = os.path.join(folder, "save_render.png")
            api.save_png(linear, path, scene)
            expected = _read_png(path)[::-1, :, :3]
            drawn = linear[..., 3] > 0
            diff = np.abs(shown[drawn, :3] - expected[drawn]) * 255.0
            rows[name] = [round(float(diff.mean()), 3), round(float(diff.max()), 2), int(drawn.sum())]
    finally:
        view.view_transform, view.look, view.exposure, view.gamma = saved
    out["per_transform"] = rows


def side_by_side(out, mod, folder):
    """The PRT view (as the overlay draws it) beside Cycles, direct light, same camera and view."""
    import time

    import numpy as np

    api = importlib.import_module(mod("blender").__name__.rsplit(".", 1)[0] + ".api")
    scene = bpy.context.scene
    prt = api.render_view(scene, display=True)[::-1]  # row 0 at the bottom, as images store it
    engine = scene.render.engine
    scene.render.engine = "CYCLES"
    scene.cycles.samples, scene.cycles.device, scene.cycles.max_bounces = 64, "CPU", 0
    scene.cycles.use_denoising = False  # (Debian's build has no OpenImageDenoise)
    scene.render.film_transparent = True
    start = time.perf_counter()
    bpy.ops.render.render()
    out["cycles_seconds"] = round(time.perf_counter() - start, 2)
    path = os.path.join(folder, "cycles.png")
    settings = scene.render.image_settings
    settings.file_format, settings.color_mode, settings.color_depth = "PNG", "RGBA", "8"
    bpy.data.images["Render Result"].save_render(path, scene=scene)
    scene.render.engine = engine
    cycles = _read_png(path)
    grey = np.array([0.23, 0.23, 0.23])  # (a display-referred background for both)
    panels = []
    for image in (prt, cycles):
        alpha = image[..., 3:4]
        panels.append(np.concatenate([image[..., :3] * alpha + grey * (1.0 - alpha), np.ones_like(alpha)], -1))
    gap = np.ones((SIZE[1], 8, 4), np.float32)
    _write_png(np.concatenate([panels[0], gap, panels[1]], axis=1), os.path.join(folder, "prt_vs_cycles.png"))
    both = (prt[..., 3] > 0) & (cycles[..., 3] > 0.99)
    out["prt_vs_cycles_mean_rgb"] = [
        prt[both, :3].mean(axis=0).round(4).tolist(),
        cycles[both, :3].mean(axis=0).round(4).tolist(),
    ]


def prepare(ctx):
    """Nothing selected, no object outlines, no light markers: the compared pixels are the
    overlay's shading alone (the markers are lines in the lights' colours, not radiance)."""
    _selected[:] = [obj.name for obj in bpy.context.scene.objects if obj.select_get()]
    display = bpy.context.scene.prt_display
    _markers[:] = [display.show_light_directions]
    display.show_light_directions = False
    for obj in bpy.context.scene.objects:
        obj.select_set(False)
    ctx["area"].spaces.active.shading.show_object_outline = False
    ctx["area"].tag_redraw()


def step(result, mod, ctx):
    """One tick of the colour phase: -> seconds until the next, or None when done. The later
    ticks, each after the event loop has run: whether the add-on's own timer builds a dropped table
    again without marking a saved file modified, and builds a new one after a change of the view
    transform."""
    ticks = result.setdefault("colour_ticks", 0)
    result["colour_ticks"] += 1
    if ticks == 0:
        run(result, mod, ctx)
        with bpy.context.temp_override(**ctx):
            bpy.ops.wm.save_as_mainfile(filepath=os.path.join(os.getcwd(), "colour", "saved.blend"))
        return 1.0
    out, colour = result["colour"], mod("blender.display.colour")
    scene = bpy.context.scene
    if ticks == 1:
        out["dirty_after_save"] = bpy.data.is_dirty
        colour.clear()  # (the timer, every 0.25 s, builds it again)
        return 1.0
    if ticks == 2:
        out["dirty_after_table_build"] = bpy.data.is_dirty
        out["timer_rebuilt_table"] = colour.view_key(scene) in colour._tables
        scene.view_settings.view_transform = "Filmic"
        return 1.0
    out["timer_followed_filmic"] = colour.view_key(scene) in colour._tables
    scene.view_settings.view_transform = "AgX"
    for name in _selected:  # (the long bake that follows bakes the selection)
        bpy.context.scene.objects[name].select_set(True)
    scene.prt_display.show_light_directions = bool(_markers and _markers[0])
    return None


def run(result, mod, ctx):
    """Every colour measurement into result["colour"]; an exception is recorded, not raised."""
    import traceback

    colour = mod("blender.display.colour")
    scene = bpy.context.scene
    out = result["colour"] = {"view_transform": scene.view_settings.view_transform}
    out["table_built_by_timer"] = colour.view_key(scene) in colour._tables  # (nothing else built it)
    folder = os.path.join(os.getcwd(), "colour")
    os.makedirs(folder, exist_ok=True)
    for step in (
        lambda: screen_against_offscreen(out, mod, ctx, folder),
        lambda: add_camera(scene),
        lambda: transforms_against_save_render(out, mod, folder),
        lambda: side_by_side(out, mod, folder),
    ):
        try:
            step()
        except Exception:
            out.setdefault("errors", []).append(traceback.format_exc())


def passed(r):
    c = r.get("colour", {})
    rows = c.get("per_transform", {})
    return (
        bool(c.get("table_built_by_timer"))
        and c.get("view_transform") == "AgX"
        and (c.get("screen_pixels_compared") or 0) > 2000
        and (c.get("screen_vs_offscreen_mean") or 99) <= SUPPORTED_LIMIT
        and {"Standard", "AgX", "Filmic", "Khronos PBR Neutral"} <= set(rows)
        and all(mean <= SUPPORTED_LIMIT for name, (mean, _max, _n) in rows.items() if name not in APPROXIMATE)
        and c.get("dirty_after_save") is False
        and c.get("dirty_after_table_build") is False
        and bool(c.get("timer_rebuilt_table"))
        and bool(c.get("timer_followed_filmic"))
        and "errors" not in c
    )
