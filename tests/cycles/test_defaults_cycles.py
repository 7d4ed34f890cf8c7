"""The default preset against Cycles' default in a closed room lit through a skylight (interior.exr)."""

import numpy as np
import pytest
from helpers.cycles import cycles_vertex_bake
from helpers.skylight_room import skylight_room

from prt_addon import api
from prt_addon.blender.bake.presets import CYCLES_DIFFUSE_BOUNCES, PRESETS
from prt_addon.core.trace import raytrace

pytestmark = pytest.mark.skipif(not raytrace.EMBREE_AVAILABLE, reason="embreex not available")

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
GROUPS = {
    "floor": ("floor",),
    "walls": ("wall_red", "wall_white", "wall_front"),
    "back wall (one quad)": ("wall_back",),
    "ceiling": ("ceiling",),
    "box": ("box",),
}
# PRT / Cycles per group, from measurements (docs/bake.md, "Defaults"): walls 0.96-1.04, ceiling
# 0.95, box 1.00, floor 0.91 (the order-4 band limit of the sky seen through the skylight: its
# direct part is 0.86 of Cycles' direct at order 4, 1.01 at order 8), the single-quad back wall
# 0.76 (its four vertices sit in the room's corners, where Cycles' own value moved by 15 % from
# seed to seed at 1024 samples).
BOUNDS = {
    "floor": (0.84, 1.08),
    "walls": (0.90, 1.10),
    "back wall (one quad)": (0.6, 1.25),
    "ceiling": (0.88, 1.10),
    "box": (0.92, 1.08),
}


def group_ratios(ours, theirs):
    """{group: mean luminance of ours / mean luminance of theirs} over each group's elements."""
    ratios = {}
    for group, names in GROUPS.items():
        mine = np.concatenate([ours[n] for n in names]) @ LUMINANCE
        cycles = np.concatenate([theirs[n] for n in names]) @ LUMINANCE
        ratios[group] = float(mine.mean() / cycles.mean())
    return ratios


def test_the_default_preset_gives_what_cycles_gives_in_a_skylit_room(bpy_module, empty_scene):
    bpy = bpy_module
    objs = [o for o in skylight_room(bpy, empty_scene, quad_back_wall=True) if o.name != "table"]
    _label, _tip, order, samples, bounces = PRESETS["GOOD"]
    assert bounces == CYCLES_DIFFUSE_BOUNCES
    api.project_world(empty_scene, order)
    direct = api.bake(objs, order=order, samples=samples)
    assert direct.enclosed_note()  # (most rays hit a wall: the report proposes bounces)
    dark = {o.name: api.shade(o, empty_scene) for o in objs}
    api.bake(objs, order=order, samples=samples, bounces=bounces)
    ours = {o.name: api.shade(o, empty_scene) for o in objs}
    flat = [o for o in objs if len(ours[o.name]) != len(o.data.vertices)]  # (the box: per corner)
    theirs = cycles_vertex_bake(
        bpy, empty_scene, [o for o in objs if o not in flat], 1024, ("DIRECT", "INDIRECT"), CYCLES_DIFFUSE_BOUNCES
    )
    theirs.update(
        cycles_vertex_bake(bpy, empty_scene, flat, 1024, ("DIRECT", "INDIRECT"), CYCLES_DIFFUSE_BOUNCES, "CORNER")
    )
    ratios = group_ratios(ours, theirs)
    for group, (low, high) in BOUNDS.items():
        assert low <= ratios[group] <= high, (group, ratios)
    # Without bounces (measured: floor 0.15, walls 0.31-0.66, back wall 0.10, ceiling 0.00) every
    # group but the box, which sees the skylight's light most directly, is far outside its bounds.
    without = group_ratios(dark, theirs)
    for group in ("floor", "walls", "back wall (one quad)", "ceiling"):
        assert without[group] < 0.75 * BOUNDS[group][0], (group, without)
