"""The scene's display transform as a 3D lookup table made by Blender's own colour management.

Blender draws a Python POST_VIEW overlay into a display-referred sRGB buffer and applies no view
transform to it, so the PRT fragment shaders apply it themselves (docs/display.md, Colour
management). The table is built by Blender: a float image whose pixels are the table's nodes
goes through `Image.save_render` on a temporary scene carrying the user's display device, view
transform, look, gamma, curve mapping and white balance (exposure stays a scale in the shader:
it is a plain multiplication of scene-linear values before all of these), and is read back from
a 16-bit PNG. The nodes are spaced evenly in log2 around 0.18 over the range AgX itself covers
(about 25 stops), node 0 being exactly black. The shader looks the table up once per pixel
(hardware trilinear filtering) and writes code^2.2: Blender's display shader turns overlay values
into display code values as value^(1/2.2) (measured on screen in Blender 4.3, docs/display.md).

Tables are built outside drawing: by a timer that compares a key of every window's view
settings (`register_timer`), or on demand by offscreen renders (`ensure_table`). The draw
callback only uploads a finished table as a 3D texture, once.
"""

import os
import tempfile

import bpy
import gpu
import numpy as np

from .. import caches
from .redraw import tag_redraw

LUT_SIZE = 66  # nodes per axis, 0.385 stop apart; node 39 is exactly 1.0, where Standard and Raw clip
LOG2_MIN = -15.0  # log2 of the scene-linear range covered (about the range of AgX's own shaper)
LOG2_MAX = 10.0
CHECK_INTERVAL = 0.25  # seconds between the timer's comparisons of the view settings
MAX_TABLES = 4  # tables kept (one per view-settings key: several windows, quick toggles)
LUT_SLOT = 9  # sampler slot: 0 is the transfer texture, 1 and 2 the shadow maps (shader_suns)
MERGE_GAMMA = 2.2  # Blender merges the overlay as overlay^(1/2.2) into its display code values

GLSL = f"""
vec3 display_transform(vec3 linear)
{{
  if (display_mode == 0) {{
    return linear;
  }}
  vec3 t = (log2(max(linear, vec3(1.0e-30))) - ({LOG2_MIN})) / {LOG2_MAX - LOG2_MIN};
  t = clamp(t, 0.0, 1.0) * {(LUT_SIZE - 1) / LUT_SIZE} + {0.5 / LUT_SIZE};
  return pow(texture(display_lut, t).rgb, vec3({MERGE_GAMMA}));
}}
"""

_tables = {}  # view key -> (n, n, n, 3) float32 display-encoded values, r fastest
_textures = {}  # view key -> GPUTexture of that table
_state = {"last": None, "dummy": None}  # last key built; a 2^3 texture bound when drawing linear
_failed = set()  # keys whose build raised: the timer does not try them again
_COPIED = ("view_transform", "look", "gamma", "use_curve_mapping")
_WHITE_BALANCE = ("use_white_balance", "white_balance_temperature", "white_balance_tint")  # 4.5+


def declare(info):
    """Add the table's sampler and the mode switch to a shader create-info."""
    info.sampler(LUT_SLOT, "FLOAT_3D", "display_lut")
    info.push_constant("INT", "display_mode")


def _curve_key(view):
    mapping = view.curve_mapping
    curves = tuple(tuple((p.location[0], p.location[1], p.handle_type) for p in c.points) for c in mapping.curves)
    return curves, tuple(mapping.black_level), tuple(mapping.white_level)


def view_key(scene):
    """Everything of the scene's colour management the table holds (not exposure)."""
    view = scene.view_settings
    key = [scene.display_settings.display_device] + [getattr(view, name) for name in _COPIED]
    key += [getattr(view, name, None) for name in _WHITE_BALANCE]
    if view.use_curve_mapping:
        key.append(_curve_key(view))
    return tuple(key)


def node_values(size=LUT_SIZE):
    """The scene-linear value of each node along one axis (node 0 is exactly black)."""
    values = 2.0 ** (LOG2_MIN + np.arange(size) / (size - 1) * (LOG2_MAX - LOG2_MIN))
    values[0] = 0.0
    return values


def _copy_view(scene, target):
    target.display_settings.display_device = scene.display_settings.display_device
    src, dst = scene.view_settings, target.view_settings
    dst.view_transform = src.view_transform
    dst.look = src.look
    dst.exposure = 0.0
    dst.gamma = src.gamma
    for name in _WHITE_BALANCE:
        if hasattr(src, name):
            setattr(dst, name, getattr(src, name))
    dst.use_curve_mapping = src.use_curve_mapping
    if src.use_curve_mapping:
        cm_src, cm_dst = src.curve_mapping, dst.curve_mapping
        cm_dst.black_level, cm_dst.white_level = cm_src.black_level, cm_src.white_level
        for c_src, c_dst in zip(cm_src.curves, cm_dst.curves):
            while len(c_dst.points) < len(c_src.points):
                c_dst.points.new(0.5, 0.5)
            while len(c_dst.points) > len(c_src.points):
                c_dst.points.remove(c_dst.points[-1])
            for p_src, p_dst in zip(c_src.points, c_dst.points):
                p_dst.location, p_dst.handle_type = p_src.location, p_src.handle_type
        cm_dst.update()


def build_table(scene, size=LUT_SIZE):
    """(size, size, size, 3) float32: Blender's display-encoded output at every node, indexed
    [b, g, r]. Creates and removes a temporary scene and two images (not from a draw callback)."""
    values = node_values(size)
    b, g, r = np.meshgrid(values, values, values, indexing="ij")
    pixels = np.stack([r, g, b, np.ones_like(r)], axis=-1).astype(np.float32)  # (b, g, r, 4)
    temp = bpy.data.scenes.new("prt_display_lut")
    source = loaded = None
    fd, path = tempfile.mkstemp(suffix=".png", prefix="prt_lut_", dir="/dev/shm" if os.path.isdir("/dev/shm") else None)
    os.close(fd)
    try:
        _copy_view(scene, temp)
        settings = temp.render.image_settings
        settings.file_format = "PNG"  # (OpenEXR output gets no view transform)
        settings.color_mode = "RGB"
        settings.color_depth = "16"
        settings.compression = 0
        source = bpy.data.images.new("prt_display_lut", size, size * size, alpha=True, float_buffer=True)
        source.pixels.foreach_set(pixels.ravel())  # row y = b * size + g, column r
        source.save_render(path, scene=temp)
        loaded = bpy.data.images.load(path)
        loaded.colorspace_settings.name = "Non-Color"  # the stored values, not decoded
        out = np.empty(size**3 * 4, dtype=np.float32)
        loaded.pixels.foreach_get(out)
    finally:
        for image in (source, loaded):
            if image is not None:
                bpy.data.images.remove(image)
        bpy.data.scenes.remove(temp)
        os.unlink(path)
    return out.reshape(size, size, size, 4)[..., :3].copy()


def ensure_table(scene):
    """Build the table of the scene's view settings unless it is kept already; -> its key."""
    key = view_key(scene)
    if key not in _tables:
        while len(_tables) >= MAX_TABLES:
            old = next(iter(_tables))
            del _tables[old]
            _textures.pop(old, None)
        _tables[key] = build_table(scene)
    _state["last"] = key
    return key


def _upload(table):
    n = table.shape[0]
    rgba = np.concatenate([table, np.ones(table.shape[:3] + (1,), np.float32)], axis=-1)
    return gpu.types.GPUTexture((n, n, n), format="RGBA16F", data=gpu.types.Buffer("FLOAT", rgba.size, rgba.ravel()))


def texture(scene, build=False):
    """The 3D texture of the scene's display transform, or None when no table exists yet.

    build=False (draw callbacks): never builds a table; while the timer has not yet built the
    table of new settings, the last one built is used. build=True builds it first.
    """
    key = ensure_table(scene) if build else view_key(scene)
    if key not in _tables:
        key = _state["last"]
        if key not in _tables:
            return None
    tex = _textures.get(key)
    if tex is None:
        tex = _textures[key] = _upload(_tables[key])
    return tex


def bind(shader, lut):
    """Set the shader's display mode: lut None draws linear values, else through the table."""
    if lut is None:
        if _state["dummy"] is None:  # (a sampler is bound even when it is not read)
            _state["dummy"] = _upload(np.zeros((2, 2, 2, 3), np.float32))
        shader.uniform_int("display_mode", 0)
        shader.uniform_sampler("display_lut", _state["dummy"])
    else:
        shader.uniform_int("display_mode", 1)
        shader.uniform_sampler("display_lut", lut)


def encode_display(linear):
    """The display code values Blender shows for overlay values (numpy, any shape): the overlay
    buffer stores them sRGB-encoded, and Blender's display shader decodes them and merges them into
    the display code values as linear^(1/2.2)."""
    x = np.clip(np.asarray(linear, dtype=np.float32), 0.0, 1.0)
    return np.power(x, 1.0 / MERGE_GAMMA).astype(np.float32)


def _check():
    """Timer: build the table of every window's scene (and the context's) whose view settings changed."""
    wm = getattr(bpy.context, "window_manager", None)
    scenes = [window.scene for window in wm.windows] if wm is not None else []
    scenes.append(getattr(bpy.context, "scene", None))
    changed = False
    for scene in scenes:
        key = view_key(scene) if scene is not None else None
        if key is not None and key not in _tables and key not in _failed:
            try:
                ensure_table(scene)
            except Exception as exc:  # (a failed build must not stop the timer)
                _failed.add(key)
                print(f"PRT Lighting: display transform not built, colours drawn linear: {exc}")
                continue
            changed = True
    if changed:
        tag_redraw()
    return CHECK_INTERVAL


def register_timer():
    if not bpy.app.timers.is_registered(_check):
        bpy.app.timers.register(_check, first_interval=0.0, persistent=True)


def unregister_timer():
    if bpy.app.timers.is_registered(_check):
        bpy.app.timers.unregister(_check)
    clear()


@caches.on_clear
def clear():
    """Drop every table and texture (file load, unregister)."""
    _tables.clear()
    _textures.clear()
    _failed.clear()
    _state["last"] = None
    _state["dummy"] = None
