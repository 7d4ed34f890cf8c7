"""Interreflected transfer in the viewport: the overlay draws the bounced bake as api.shade computes it."""

import numpy as np
import pytest
from helpers.rooms import open_room

from prt_addon import api
from prt_addon.core.trace import raytrace

pytestmark = pytest.mark.skipif(not raytrace.EMBREE_AVAILABLE, reason="embreex not available")


@pytest.mark.parametrize(("order", "hdri"), [(2, None), (4, "courtyard")])
def test_viewport_draws_the_bounced_transfer_as_shade_computes_it(bpy_module, empty_scene, order, hdri):
    """Order 2 in colour fits the vertex attributes, order 4 in colour (16 vec4s) uses the
    transfer texture; under courtyard.exr the split lights' SH lights the bounced part."""
    import math

    from prt_addon.blender.display import offscreen

    assert offscreen.ensure_gpu()
    bpy = bpy_module
    objs = open_room(bpy, empty_scene, hdri=hdri)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    empty_scene.collection.objects.link(cam)
    cam.location, cam.rotation_euler = (0.0, -7.0, 5.0), (math.radians(55), 0.0, 0.0)
    empty_scene.camera = cam
    empty_scene.prt_display.albedo_source = "WHITE"
    api.project_world(empty_scene, order)
    api.bake(objs, order=order, samples=64, bounces=2)
    size = 256
    image = api.render_view(empty_scene, size, size)
    floor = objs[0]
    expected = api.shade(floor, empty_scene)
    p = np.array([floor.matrix_world @ v.co for v in floor.data.vertices])
    depsgraph = bpy.context.evaluated_depsgraph_get()
    proj = np.array(cam.calc_matrix_camera(depsgraph, x=size, y=size)) @ np.array(cam.matrix_world.inverted())
    clip = np.c_[p, np.ones(len(p))] @ proj.T
    ndc = clip[:, :2] / clip[:, 3:4]
    cols = np.floor((ndc[:, 0] + 1) * 0.5 * size).astype(int)
    rows = np.floor((1 - ndc[:, 1]) * 0.5 * size).astype(int)
    inside = (cols >= 1) & (cols < size - 1) & (rows >= 1) & (rows < size - 1) & (np.abs(p[:, 0]) < 1.8)
    inside &= (p[:, 1] > -1.8) & (p[:, 1] < 1.8) & (np.hypot(p[:, 0], p[:, 1]) > 1.2)  # not behind Suzanne
    got = image[rows[inside], cols[inside], :3]
    want = expected[inside]
    err = np.abs(got - want) / (np.abs(want) + 0.05)
    assert inside.sum() > 40
    # Under courtyard the split lights are four patches of 4 to 23 degrees (45 % of the power):
    # their shadows come from maps, where api.shade traces rays (docs/display.md, "Sun shadows"),
    # measured 1.6-2.0 % (api.shade itself is 0.5 % from a 64-ray-per-sample trace; one filtered
    # map per light was 6-7 %). Without split lights (order 2, uniform world) 0.18 %.
    assert np.median(err) < (0.025 if hdri else 0.01), np.median(err)
