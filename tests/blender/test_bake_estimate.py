"""The estimate before a bake (elements, rays, memory), the refusal past the available memory,
and the report's proposal of bounces for an enclosed scene."""

import tracemalloc

import pytest
from helpers.bake_scenes import _attr_bytes, _monkey_on_ground
from helpers.skylight_room import skylight_room

from prt_addon import api


def test_estimate_counts_the_points_and_rays_the_bake_computes(bpy_module, empty_scene):
    bpy = bpy_module
    ground, monkey = _monkey_on_ground(bpy, ground_cuts=20)
    bpy.ops.mesh.primitive_cube_add(location=(2.0, 2.0, 0.5))  # flat-shaded: 24 corners with their own normal
    cube = bpy.context.object
    objects = [ground, monkey, cube]
    found = api.estimate_bake(objects, order=4, samples=64)
    report = api.bake(objects, order=4, samples=64)
    assert found["elements"] == report.points  # (the bake's own count: vertices, or split corners)
    assert found["rays"] == report.rays_traced + report.rays_skipped
    assert report.estimate_seconds == pytest.approx(found["seconds"], rel=0.2)
    assert 0 < found["bytes"] < found["available"] and found["fits"]
    # Memory grows with the coefficients, and bounces add the nodes and their hits.
    # (linearly in order^2 over a fixed part: 64 - 16 coefficients are 4 times 16 - 4)
    b2, b8 = (api.estimate_bake(objects, order=n, samples=64)["bytes"] for n in (2, 8))
    assert b8 - found["bytes"] == pytest.approx(4 * (found["bytes"] - b2), rel=1e-3)
    bounced = api.estimate_bake(objects, order=4, samples=64, bounces=4)
    assert bounced["bytes"] > found["bytes"] and bounced["seconds"] > found["seconds"]
    # A camera or a light in the selection counts nothing.
    bpy.ops.object.camera_add()
    assert api.estimate_bake([*objects, bpy.context.object], order=4, samples=64)["elements"] == report.points


def test_a_bake_past_the_available_memory_is_refused_before_it_starts(bpy_module, empty_scene, monkeypatch):
    from prt_addon.blender.bake import estimate

    bpy = bpy_module
    ground, monkey = _monkey_on_ground(bpy)
    api.bake([ground, monkey], order=2, samples=16)
    before = {o.name: _attr_bytes(o.data) for o in (ground, monkey)}
    need = api.estimate_bake([ground, monkey], order=8, samples=256)["bytes"]
    monkeypatch.setattr(estimate, "available_memory", lambda: need)  # (the bake may take 90 % of it)
    assert not api.estimate_bake([ground, monkey], order=8, samples=256)["fits"]
    with pytest.raises(ValueError, match="would take about .* of memory and .* are available: lower the order"):
        api.bake([ground, monkey], order=8, samples=256)
    assert {o.name: _attr_bytes(o.data) for o in (ground, monkey)} == before
    monkeypatch.setattr(estimate, "available_memory", lambda: 2 * need)
    assert api.bake([ground, monkey], order=8, samples=256).ok


def test_an_enclosed_scene_baked_without_bounces_is_told_to_bake_them(bpy_module, empty_scene):
    bpy = bpy_module
    room = skylight_room(bpy, empty_scene)
    report = api.bake(room, order=2, samples=32)
    # Every front ray from inside but the skylight's hits a wall; the single-quad walls' back
    # sides face outwards, and do not make the room less enclosed.
    assert report.enclosed_share > 0.9
    assert "Bounces 4" in report.enclosed_note()
    assert report.enclosed_note() in report.report_lines()
    assert api.bake(room, order=2, samples=32, bounces=4).enclosed_note() == ""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    ground, monkey = _monkey_on_ground(bpy)  # open: most rays escape
    assert api.bake([ground, monkey], order=2, samples=32).enclosed_note() == ""


def _traced_peak(bake):
    """The peak of the Python and numpy allocations while bake() runs (tracemalloc), in bytes."""
    tracemalloc.start()
    try:
        bake()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize(
    "kind",
    [
        {"order": 4, "samples": 128, "bounces": 3},
        {"order": 4, "samples": 128, "target": "TEXELS", "resolution": 32},
        {"order": 4, "samples": 128, "target": "TEXELS", "resolution": 32, "bounces": 2},
    ],
    ids=["vertex-bounces", "texel-adaptive", "texel-bounces"],
)
def test_the_memory_estimate_bounds_a_bakes_peak(bpy_module, empty_scene, kind):
    """Vertex and texel bakes, with and without bounces: the estimate is above the measured peak
    (it counts the worst case: every texel covered, every hit-traced ray above the surface
    hitting) and within a few times it (docs/bake.md, "Estimates": measured 1.1 to 4.6)."""
    from helpers import texel_scenes

    objs = texel_scenes.low_poly_room(bpy_module)
    options = dict(kind, uv_map=texel_scenes.LIGHTMAP) if "target" in kind else dict(kind)
    found = api.estimate_bake(objs, **options)
    peak = _traced_peak(lambda: api.bake(objs, **options))
    assert peak <= found["bytes"] <= 8 * peak, (peak, found["bytes"])


def test_a_texel_bake_past_the_memory_is_refused_with_nothing_written(bpy_module, empty_scene, monkeypatch):
    from helpers import texel_scenes

    from prt_addon.blender.bake import estimate

    objs = texel_scenes.low_poly_room(bpy_module)
    before = {o.name: (_attr_bytes(o.data), [uv.name for uv in o.data.uv_layers]) for o in objs}
    images = set(bpy_module.data.images.keys())
    options = {"order": 8, "samples": 64, "target": "TEXELS", "resolution": 64, "bounces": 2}
    options["uv_map"] = texel_scenes.LIGHTMAP
    need = api.estimate_bake(objs, **options)["bytes"]
    monkeypatch.setattr(estimate, "available_memory", lambda: need)
    with pytest.raises(ValueError, match="would take about .* of memory and .* are available"):
        api.bake(objs, **options)
    assert {o.name: (_attr_bytes(o.data), [uv.name for uv in o.data.uv_layers]) for o in objs} == before
    assert set(bpy_module.data.images.keys()) == images
