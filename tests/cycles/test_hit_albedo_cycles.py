"""The bounced light off a single-quad wall carrying a red/blue image, against Cycles' indirect bake
of the floor beside it: each half's colour where it is (the albedo at each hit)."""

import numpy as np
import pytest
from helpers.cycles import cycles_vertex_bake
from helpers.textured_wall import room

from prt_addon import api
from prt_addon.core.trace import raytrace

pytestmark = pytest.mark.skipif(not raytrace.EMBREE_AVAILABLE, reason="embreex not available")


def test_textured_quad_wall_bounce_matches_cycles(bpy_module, empty_scene):
    bpy, scene = bpy_module, empty_scene
    floor = room(bpy, scene, textured=True)
    api.project_world(scene, 4)
    api.bake([floor], order=4, samples=512)
    direct = api.shade(floor, scene)
    api.bake([floor], order=4, samples=512, bounces=1)
    ours = api.shade(floor, scene) - direct  # (the uniform world's direct light is exact at any order)
    c_direct = cycles_vertex_bake(bpy, scene, [floor], 256, bounces=0)[floor.name]
    theirs = cycles_vertex_bake(bpy, scene, [floor], 256, ("DIRECT", "INDIRECT"), 1)[floor.name] - c_direct
    co = np.array([v.co[:] for v in floor.data.vertices])
    near = co[:, 0] < -1.0
    for side in (co[:, 1] < -0.7, co[:, 1] > 0.7):  # by the red half, by the blue half
        ours_side, theirs_side = ours[near & side].mean(axis=0), theirs[near & side].mean(axis=0)
        print("ours", ours_side, "cycles", theirs_side)
        # The colour (the albedo where the rays hit): each channel's share of the bounce.
        np.testing.assert_allclose(ours_side / ours_side.sum(), theirs_side / theirs_side.sum(), atol=0.03)
        # The amount: the one quad's four bounce nodes interpolate its light linearly over 4 m
        # (green, whose albedo is the same everywhere, is as far off as red).
        np.testing.assert_allclose(ours_side, theirs_side, rtol=0.15)
