"""Interreflected bakes against Cycles: an open room under a uniform world, city.exr and courtyard.exr."""

import numpy as np
import pytest
from helpers.cycles import cycles_vertex_bake
from helpers.rooms import open_room

from prt_addon import api
from prt_addon.core.trace import raytrace

pytestmark = pytest.mark.skipif(not raytrace.EMBREE_AVAILABLE, reason="embreex not available")


def lights_bounce(obj, scene):
    """The part of obj's shading that is the split lights' bounced light (their SH through the
    bounced transfer), per element and channel."""
    from prt_addon.blender.scene import lighting, storage

    info, _ = storage.usable_bake(obj.data)
    bounced = storage.read_bounce(obj.data, info).astype(np.float64)
    extra = lighting.bounce_light_extra(obj, lighting.world_lights(scene), info.order)
    return np.stack([bounced[:, min(c, bounced.shape[1] - 1)] @ extra[:, c] for c in range(3)], axis=1)


def test_open_room_bounces_match_cycles_and_the_red_wall_bleeds(bpy_module, empty_scene):
    """city.exr: a small, bright sun split off as a light; its light reaches the room's floor and
    walls through the open top and must bounce (Cycles bounces every light)."""
    bpy = bpy_module
    objs = open_room(bpy, empty_scene, hdri="city")
    api.project_world(empty_scene, 8)
    assert api.world_lights(empty_scene)
    api.bake(objs, order=8, samples=512)
    direct = {o.name: api.shade(o, empty_scene) for o in objs}
    report = api.bake(objs, order=8, samples=512, bounces=3)
    assert report.bounces == 3
    assert report.bounce_channels == 3
    bounced = {o.name: api.shade(o, empty_scene) for o in objs}
    c_direct = cycles_vertex_bake(bpy, empty_scene, objs, 256, bounces=0)
    c_total = cycles_vertex_bake(bpy, empty_scene, objs, 256, ("DIRECT", "INDIRECT"), 3)
    for obj in objs:
        ours = bounced[obj.name] - direct[obj.name]  # the indirect part: the direct band limit cancels
        theirs = c_total[obj.name] - c_direct[obj.name]
        without_lights = ours - lights_bounce(obj, empty_scene)
        # Per object and channel, the mean indirect light. Under a uniform world it agreed within
        # 2 % (test below); here the bounced light also inherits the order-8 band limit of the
        # direct light it gathers, the sun's included. Without the sun's bounce it is 15 to 36 %
        # low (the sun's share of the indirect light), which this tolerance would catch.
        np.testing.assert_allclose(ours.mean(axis=0), theirs.mean(axis=0), rtol=0.08, err_msg=obj.name)
        error = np.abs(ours.mean(axis=0) - theirs.mean(axis=0)).sum()
        assert np.abs(without_lights.mean(axis=0) - theirs.mean(axis=0)).sum() > 2.0 * error, obj.name
    floor = objs[0]
    x = np.array([floor.matrix_world @ v.co for v in floor.data.vertices])[:, 0]
    for values in (bounced[floor.name] - direct[floor.name], c_total[floor.name] - c_direct[floor.name]):
        near_red, near_white = values[x < -1.2].mean(axis=0), values[x > 1.2].mean(axis=0)
        assert near_red[0] / near_red[1] > 1.3 * near_white[0] / near_white[1]


def test_uniform_world_room_matches_cycles_closely(bpy_module, empty_scene):
    bpy = bpy_module
    objs = open_room(bpy, empty_scene)
    api.project_world(empty_scene, 2)
    api.bake(objs, order=2, samples=512)
    direct = {o.name: api.shade(o, empty_scene) for o in objs}
    api.bake(objs, order=2, samples=512, bounces=3)
    bounced = {o.name: api.shade(o, empty_scene) for o in objs}
    c_direct = cycles_vertex_bake(bpy, empty_scene, objs, 128, bounces=0)
    c_total = cycles_vertex_bake(bpy, empty_scene, objs, 128, ("DIRECT", "INDIRECT"), 3)
    for obj in objs:
        ours = (bounced[obj.name] - direct[obj.name]).mean(axis=0)
        theirs = (c_total[obj.name] - c_direct[obj.name]).mean(axis=0)
        # A uniform world is exact at order 2: what is left is sampling (PRT 512 directions,
        # Cycles 128 samples) and the hit interpolation; measured 0.3 to 2 %.
        np.testing.assert_allclose(ours, theirs, rtol=0.04, err_msg=obj.name)


def test_courtyard_room_indirect_part_matches_cycles_at_1_and_3_bounces(bpy_module, empty_scene):
    """The bounced part (DIRECT + INDIRECT minus DIRECT, both from Cycles) of the open room under
    courtyard.exr at order 8. Measured per object and channel: within 3.4 % of the mean of two
    Cycles seeds at 1 and 3 bounces; Cycles' own seed-to-seed difference up to 4.2 % (256
    samples), so one seed carries about 3 %: 8 % plus that. (Order 4 is 13 to 19 % low on the
    white wall's green and blue: the band limit of the direct light it gathers.)"""
    bpy = bpy_module
    objs = open_room(bpy, empty_scene, hdri="courtyard")
    api.project_world(empty_scene, 8)
    api.bake(objs, order=8, samples=512)
    direct = {o.name: api.shade(o, empty_scene) for o in objs}
    c_direct = cycles_vertex_bake(bpy, empty_scene, objs, 256, bounces=0)
    for bounces in (1, 3):
        api.bake(objs, order=8, samples=512, bounces=bounces)
        bounced = {o.name: api.shade(o, empty_scene) for o in objs}
        c_total = cycles_vertex_bake(bpy, empty_scene, objs, 256, ("DIRECT", "INDIRECT"), bounces)
        for obj in objs:
            ours = (bounced[obj.name] - direct[obj.name]).mean(axis=0)
            theirs = (c_total[obj.name] - c_direct[obj.name]).mean(axis=0)
            np.testing.assert_allclose(ours, theirs, rtol=0.11, err_msg=f"{obj.name}, {bounces} bounce(s)")
