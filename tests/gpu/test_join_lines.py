"""Joins of a single-quad room lit through a skylight: no lit lines along them in the view's split-light part, and none in api.shade at the room's corners."""

import numpy as np
import pytest
from helpers import skylight_quads as room

from prt_addon.core.trace import raytrace

pytestmark = pytest.mark.skipif(not raytrace.EMBREE_AVAILABLE, reason="embreex not available")

DISTANCES = (0.005, 0.01, 0.02, 0.15)  # metres from the join on the receiver


@pytest.fixture(scope="module")
def courtyard_room(bpy_module, addon, gpu_ready):
    """The room baked (order 2), drawn with courtyard's split lights and with none; the joins'
    bands (helpers.skylight_quads.join_bands) and the dense lights."""
    import prt_addon.api as api

    bpy = bpy_module
    scene, objects, lights, image, sky, shade_sky = room.baked_views(bpy, "courtyard", shade_sky=True)
    shade = {obj.name: api.shade(obj, scene) - shade_sky[obj.name] for obj in objects[:5]}
    dense = room.dense_lights(scene, lights)
    bands = room.join_bands(bpy, scene, image, sky, dense, DISTANCES)
    return bpy, scene, dense, bands, shade


@pytest.mark.parametrize("join", sorted(room.JOINS))
def test_no_lit_line_along_join(courtyard_room, join):
    """Along each join (wall-wall, wall-ceiling, wall-floor, the box's foot) the view's split-light
    part 0.5 to 2 cm from it is within 0.003 (a tenth of the left wall's skylight patch) of
    the lights traced over 1024 power cells each, as it is 15 cm away. Before, PCF taps that
    crossed the join in the map onto columns holding nothing before the receiver's plane (rays
    passing outside the closed room, or under the floor to the box's foot) counted as lit, and
    the contact shift moved a single quad's lookups 1.4 biases off the join: the left wall drew
    0.034 under the ceiling and 0.027 over the floor, the right wall 0.020 over the floor, the
    box's west side 0.022 at its foot, where the trace has 0, 0.002, 0 and 0."""
    _bpy, _scene, _dense, bands, _shade = courtyard_room
    view, traced = bands[join]
    print(join, " ".join(f"{v:.4f}/{t:.4f}" for v, t in zip(view, traced)))
    np.testing.assert_array_less(np.abs(view - traced), 0.003 + 0.25 * traced)


@pytest.mark.parametrize("wall", ["back", "left", "right", "floor"])
def test_api_shade_has_no_lit_corners(courtyard_room, wall):
    """api.shade at a wall's four vertices (the room's corners, where its joins meet; its rays
    start moved into the wall along the contact tangent): its split-light part within 0.003 +
    25 % of the same 16 samples per light traced 1 cm inside the corner along the diagonal, and
    never above the lights traced there over 1024 power cells each by more than that (no lit
    corner). (The floor's and back wall's back-left corner get 0.008 to 0.015 from the dense
    trace and 0 from 16 samples: a sampling difference, not a join's.)"""
    from prt_addon.blender.scene import lighting
    from prt_addon.core.lights import visibility

    bpy, scene, dense, _bands, shade = courtyard_room

    occluder, _ranges = room._occluder(bpy, scene)
    obj = bpy.data.objects[wall]
    mw = np.array(obj.matrix_world)
    corners = np.array([v.co for v in obj.data.vertices]) @ mw[:3, :3].T + mw[:3, 3]
    normal = np.cross(corners[1] - corners[0], corners[3] - corners[0])
    normal /= np.linalg.norm(normal)
    towards = corners.mean(axis=0) - corners
    inside = corners + 0.01 * towards / np.linalg.norm(towards, axis=1, keepdims=True)
    n = np.tile(normal, (4, 1))
    traced = {}
    for key, lights in (("16", lighting.world_lights(scene)), ("dense", dense)):
        seen = visibility.light_visibility(inside, n, lights, occluder, offset=1e-3)
        traced[key] = visibility.light_irradiance(n, lights, seen) @ room.LUMA
    ours = shade[wall] @ room.LUMA
    print(wall, ours.round(4), traced["16"].round(4), traced["dense"].round(4))
    np.testing.assert_array_less(np.abs(ours - traced["16"]), 0.003 + 0.25 * traced["16"])
    np.testing.assert_array_less(ours - traced["dense"], 0.003 + 0.25 * traced["dense"])
