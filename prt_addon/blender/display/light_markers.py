"""Markers of the split lights' directions in the 3D viewport, drawn with the gpu builtin shaders.

For each split light (lighting.world_lights: world space, the Mapping rotation applied now) a line
from the 3D cursor toward the light and, at its tip, a circle of the light's angular radius as
seen from the cursor; the colour is the light's hue (its power scaled to a largest channel of 1),
the strongest light's line the widest. The length is LENGTH_SCALE times the distance from the
eye to the cursor, so the markers keep their size on screen while zooming. Drawn on top (no
depth test) by a POST_VIEW handler of its own, installed next to the PRT draw handler
(draw.add_draw_handler), and in render_view, when Display > Light Directions is on.
"""

import bpy
import gpu
import numpy as np

from ..scene.lighting import world_lights

LENGTH_SCALE = 0.35  # line length / distance from the eye to the cursor
LINE_WIDTH = (1.5, 4.0)  # pixels: weakest and strongest light
CIRCLE_SEGMENTS = 48


def enabled(scene):
    """True when the scene's PRT display is on and shows the light directions."""
    prt, display = getattr(scene, "prt", None), getattr(scene, "prt_display", None)
    return bool(prt is not None and display is not None and prt.show_display and display.show_light_directions)


def marker_colour(power):
    """RGBA of a light: its power scaled so that the largest channel is 1 (alpha 1)."""
    p = np.maximum(np.asarray(power, dtype=np.float64), 0.0)
    top = float(p.max())
    rgb = p / top if top > 0.0 else np.ones(3)
    return (*rgb.tolist(), 1.0)


def marker_segments(lights, centre, length):
    """[(line (2, 3), circle (CIRCLE_SEGMENTS + 1, 3) closed loop, RGBA, width px)] per light,
    in world space: the line from centre to centre + length * direction, the circle about its tip,
    perpendicular to the direction, of radius length * tan(angle)."""
    if not lights:
        return []
    centre = np.asarray(centre, dtype=np.float64).reshape(3)
    strongest = max(light.luminance for light in lights) or 1.0
    turn = np.linspace(0.0, 2.0 * np.pi, CIRCLE_SEGMENTS + 1)
    out = []
    for light in lights:
        d = light.direction / np.linalg.norm(light.direction)
        tip = centre + length * d
        helper = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        u = np.cross(d, helper)
        u /= np.linalg.norm(u)
        v = np.cross(d, u)
        radius = length * np.tan(min(light.angle, 1.4))
        circle = tip + radius * (np.cos(turn)[:, None] * u + np.sin(turn)[:, None] * v)
        share = max(0.0, light.luminance) / strongest
        width = LINE_WIDTH[0] + (LINE_WIDTH[1] - LINE_WIDTH[0]) * share
        out.append((np.stack([centre, tip]), circle, marker_colour(light.power), width))
    return out


def _matrix(m):
    import mathutils

    return m if isinstance(m, mathutils.Matrix) else mathutils.Matrix(np.asarray(m, dtype=np.float64).tolist())


def draw_markers(scene, view, projection, size, centre=None):
    """Draw the scene's light markers into the bound framebuffer. view, projection: 4x4 (world
    -> eye, eye -> clip); size: (width, height) in pixels; centre: default the 3D cursor.
    Returns the number of lights drawn."""
    from gpu_extras.batch import batch_for_shader

    lights = world_lights(scene)
    if not lights:
        return 0
    view, projection = _matrix(view), _matrix(projection)
    centre = np.array(scene.cursor.location if centre is None else centre, dtype=np.float64)
    eye = np.array(view.inverted().translation, dtype=np.float64)
    if projection[3][3] == 1.0:  # orthographic: the eye is at infinity, use the view's scale
        distance = 2.0 / max(abs(projection[0][0]), 1e-9)
    else:
        distance = float(np.linalg.norm(eye - centre))
    shader = gpu.shader.from_builtin("POLYLINE_UNIFORM_COLOR")
    depth, blend = gpu.state.depth_test_get(), gpu.state.blend_get()
    gpu.state.depth_test_set("NONE")
    gpu.state.blend_set("ALPHA")
    try:
        with gpu.matrix.push_pop(), gpu.matrix.push_pop_projection():
            gpu.matrix.load_matrix(view)
            gpu.matrix.load_projection_matrix(projection)
            shader.bind()
            shader.uniform_float("viewportSize", (float(size[0]), float(size[1])))
            for line, circle, colour, width in marker_segments(lights, centre, LENGTH_SCALE * distance):
                shader.uniform_float("color", colour)
                shader.uniform_float("lineWidth", width)
                batch_for_shader(shader, "LINES", {"pos": line.astype(np.float32)}).draw(shader)
                shader.uniform_float("lineWidth", LINE_WIDTH[0])
                batch_for_shader(shader, "LINE_STRIP", {"pos": circle.astype(np.float32)}).draw(shader)
    finally:
        gpu.state.blend_set(blend)
        gpu.state.depth_test_set(depth)
    return len(lights)


def _draw_callback():
    context = bpy.context
    scene = context.scene
    region, region_data = context.region, context.region_data
    if region is None or region_data is None or not enabled(scene):
        return
    draw_markers(scene, region_data.view_matrix, region_data.window_matrix, (region.width, region.height))


_handle = None


def add_handler():
    global _handle
    if _handle is None:
        _handle = bpy.types.SpaceView3D.draw_handler_add(_draw_callback, (), "WINDOW", "POST_VIEW")
    return _handle


def remove_handler():
    global _handle
    if _handle is not None:
        try:
            bpy.types.SpaceView3D.draw_handler_remove(_handle, "WINDOW")
        except ValueError:
            pass
        _handle = None
