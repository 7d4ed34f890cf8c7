"""The real-window check's turn on screen: waits until the viewport has drawn the turned lighting,
then picks the X screenshots before and after the turn and measures how much Suzanne changed."""

import glob
import os
import time

import bpy

REDRAW_SECONDS = 2.0  # the turned lighting must be drawn within this
SETTLE_SECONDS = 2.5  # then the screen is left alone while the X screenshots (one per ~0.7 s) catch it
SHOT_DELAY = 0.8  # the screenshot of a state: the first one started this long after it was drawn
MIN_CHANGE = 2.0  # /255: the median change over Suzanne's box that counts as "the shading turned"


def screen_box(obj, ctx):
    """obj's bounding box on the window, in pixels from the window's bottom left: [x0, y0, x1, y1]."""
    from bpy_extras.view3d_utils import location_3d_to_region_2d
    from mathutils import Vector

    region, view = ctx["region"], ctx["area"].spaces.active.region_3d
    points = [location_3d_to_region_2d(region, view, obj.matrix_world @ Vector(c)) for c in obj.bound_box]
    xs = [p.x + region.x for p in points if p is not None]
    ys = [p.y + region.y for p in points if p is not None]
    return [int(min(xs)), int(min(ys)), int(max(xs)) + 1, int(max(ys)) + 1] if xs else None


def wait_turn(result, drawn):
    """One tick of the phase after the turn: -> seconds until the next, or None when done. `drawn`
    holds (phase, lights, time) per viewport draw: the first in phase "turned" drew the turn."""
    if "turn_drawn_at" in result:
        return None
    after = [t for phase, _, t in drawn if phase == "turned"]
    if after or time.time() - result["rotated_at"] > 10 * REDRAW_SECONDS:
        result["turn_drawn_at"] = after[0] if after else None
        result["turn_redraw_seconds"] = after[0] - result["rotated_at"] if after else None
        return SETTLE_SECONDS
    return 0.05


def _pixels(path):
    import numpy as np

    image = bpy.data.images.load(path, check_existing=False)
    width, height = image.size
    buf = np.empty(width * height * 4, np.float32)
    image.pixels.foreach_get(buf)
    bpy.data.images.remove(image)
    return buf.reshape(height, width, 4)[..., :3] * 255.0  # rows from the bottom, as the window's


def compare(result, folder):
    """Picks the screenshots of the display turned on and of the turn drawn (their names in
    result["turn_shots"]) and the median change of Suzanne's box between them, /255."""
    import numpy as np

    shots = sorted((float(os.path.basename(p)[7:-4]), p) for p in glob.glob(os.path.join(folder, "screen_*.png")))

    def first_after(key):
        moment = result.get(key)
        return next((p for t, p in shots if t >= moment + SHOT_DELAY), None) if moment else None

    picked = [first_after("display_on_at"), first_after("turn_drawn_at")]
    result["turn_shots"] = [os.path.basename(p) if p else None for p in picked]
    box = result.get("suzanne_box")
    if all(picked) and box:
        before, after = (_pixels(p)[box[1] : box[3], box[0] : box[2]] for p in picked)
        result["turn_viewport_change"] = float(np.median(np.abs(after - before).mean(axis=-1)))
