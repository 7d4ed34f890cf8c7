"""The light the display draws: the world's SH (or an override), rotated into each object's frame.

`shade()` computes on the CPU the radiance the shader draws, from the same local-frame light and
the same float32 transfer values, albedo excluded, plus the split lights (light_shading).
"""

import bpy
import numpy as np

from ...core.lights import extraction as _lights
from ...core.lights.light_sh import lights_sh
from ...core.sh import basis as _sh, frames as _frames, rotation as _rotation
from .. import caches
from ..display.redraw import tag_redraw
from ..world import nodes as _nodes, projection as _world
from . import back_storage, storage, texel_shading
from .light_shading import light_radiance

_light_overrides = {}  # scene key -> (n*n, 3) float64 unrotated light


def set_light_override(scene, coeffs):
    """Use `coeffs` ((n*n, 3) or (n*n,)) as the scene's unrotated light instead of the world's.

    The world's Mapping node rotation still applies (`world_light`), exactly as it would to the
    projected world. Pass None to remove. Overrides are dropped when a file loads.
    """
    if coeffs is None:
        _light_overrides.pop(_scene_key(scene), None)
    else:
        c = np.asarray(coeffs, dtype=np.float64)
        if c.ndim == 1:
            c = np.repeat(c[:, None], 3, axis=1)
        _sh.order_of(c.shape[0])
        if c.ndim != 2 or c.shape[1] != 3:
            raise ValueError(f"light coefficients must have shape (n*n, 3), got {c.shape}")
        _light_overrides[_scene_key(scene)] = c.copy()
    tag_redraw()


def _scene_key(scene):
    """A key that survives renaming the scene (its session id; the pointer on older Blender)."""
    return getattr(scene, "session_uid", None) or scene.as_pointer()


@caches.on_clear
def clear_light_overrides():
    _light_overrides.clear()
    _lights_overrides.clear()


def world_light(scene):
    """(n*n, 3) float64 world-space light SH of the scene, or None when there is none."""
    override = _light_overrides.get(_scene_key(scene))
    if override is not None:
        rot = _nodes.live_sh_rotation(scene.world)
        return override if rot is None else _rotation.rotate(override, rot)
    coeffs = _world.current_world_coeffs(scene)
    return None if coeffs is None else np.asarray(coeffs, dtype=np.float64)


_lights_overrides = {}  # scene key -> list of core.lights.extraction.Light, image frame


def set_lights_override(scene, lights):
    """Use `lights` (core.lights.extraction.Light list, image frame) as the scene's split lights instead
    of the projected ones; the Mapping rotation still applies. None removes the override."""
    if lights is None:
        _lights_overrides.pop(_scene_key(scene), None)
    else:
        _lights_overrides[_scene_key(scene)] = list(lights)
    tag_redraw()


def world_lights(scene):
    """The split lights of the scene in world space (core.lights.extraction.Light list, the Mapping rotation
    applied exactly as to the SH), [] when there are none or the split is off."""
    override = _lights_overrides.get(_scene_key(scene))
    if override is not None:
        rot = _nodes.live_sh_rotation(scene.world)
        return override if rot is None else _lights.rotate_lights(override, rot)
    return _world.current_world_lights(scene)


def light_in_local_frame(light_world, matrix_world, order):
    """(order**2, 3) light in the object's local frame: rotated by the inverse of the rotation
    part of matrix_world, truncated or zero-padded to `order`. The same frame as the bake's
    core.sh.frames.to_local_frame, applied to the light instead of the transfer."""
    n2 = order * order
    light = np.zeros((n2, 3))
    m = min(n2, light_world.shape[0])
    light[:m] = light_world[:m]
    r, parity = _frames.frame_rotation(np.asarray(matrix_world, dtype=np.float64)[:3, :3])
    if np.abs(r - np.eye(3)).max() > 1e-12:
        light = _rotation.rotate(light, r.T)
    if parity:
        light *= ((-1.0) ** _sh.band_of_index(order))[:, None]
    return light


def object_light(obj, scene, order=None):
    """The local-frame light used for obj ((order**2, 3) float64), or None without lighting."""
    light = world_light(scene)
    if light is None:
        return None
    if order is None:
        info, _ = storage.usable_bake(obj.data)
        order = info.order if info is not None else _sh.order_of(light.shape[0])
    return light_in_local_frame(light, obj.matrix_world, order)


def bounce_light_extra(obj, lights, order):
    """(order**2, 3) local-frame SH of the split lights: the light of theirs that bounces (an
    interreflected bake's bounced transfer sees the sky plus this; core.lights.light_sh)."""
    if not lights:
        return np.zeros((order * order, 3))
    return light_in_local_frame(lights_sh(lights, order), obj.matrix_world, order)


SIDES = ("FRONT", "BACK")


def shade(obj, scene=None, side="FRONT"):
    """Per-element radiance (elements, 3) float64 for a white surface: max(sum_i L_i t_i, 0) per
    channel, L in obj's local frame (what the display shader computes; with bounces,
    t = direct + bounced, the bounced part also lit by the split lights' SH), plus each split light's
    power / pi * max(0, n . s) * V with V traced against the scene's meshes
    (light_shading.light_radiance). One row per vertex for a POINT bake, per face corner for a
    CORNER bake; for a TEXEL bake (res, res, 3), one value per texel (texel_shading). side
    "BACK": the back side of an open mesh (its own transfer, the lights' cosine on the flipped
    normal; direct light only, docs/bake.md "Back faces")."""
    if side not in SIDES:
        raise ValueError(f"side must be 'FRONT' or 'BACK', not {side!r}")
    scene = scene if scene is not None else bpy.context.scene
    depsgraph = bpy.context.evaluated_depsgraph_get()  # flushes pending edits into matrix_world
    mesh = obj.data
    info, problem = storage.usable_bake(mesh)
    if info is None or problem:  # not baked, or stale (topology changed since the bake)
        raise ValueError(f"'{obj.name}': {problem}: bake it (PRT tab > Bake Transfer)")
    if side == "BACK" and not info.back:
        raise ValueError(
            f"'{obj.name}' has no back-side transfer: only open meshes (with boundary edges) have "
            "one; a closed mesh's back faces are never seen"
        )
    light = object_light(obj, scene, info.order)
    if light is None:
        raise ValueError("the scene has no PRT lighting (project the world first)")
    lights = world_lights(scene)
    if info.domain == "TEXEL":  # (res, res, 3) per texel, laid out as Image.pixels
        bounce_light = light + bounce_light_extra(obj, lights, info.order) if info.channels else None
        radiance = texel_shading.sky_radiance(info, light, bounce_light, side)
        return radiance + texel_shading.light_radiance(obj, depsgraph, lights, info, side=side) if lights else radiance
    if side == "BACK":
        transfer = back_storage.read_back(mesh, info.count, info.order).astype(np.float64)
        radiance = np.maximum(transfer @ light, 0.0)
        return radiance + light_radiance(obj, depsgraph, lights, info, side="BACK") if lights else radiance
    transfer = storage.read_transfer(mesh, info, padded=True).astype(np.float64)
    n2 = info.order * info.order
    radiance = transfer[:, :n2] @ light
    bounced = storage.read_bounce(mesh, info)
    if bounced is not None:
        full = light + bounce_light_extra(obj, lights, info.order)
        for c in range(3):  # one bounced vector per channel, or one for all (grey surfaces)
            radiance[:, c] += bounced[:, min(c, bounced.shape[1] - 1)].astype(np.float64) @ full[:, c]
    radiance = np.maximum(radiance, 0.0)
    if lights:
        radiance += light_radiance(obj, depsgraph, lights, info)
    return radiance


def exposure_scale(scene):
    """2**exposure: the scene exposure the viewport applies before its view transform."""
    return 2.0 ** float(scene.view_settings.exposure)
