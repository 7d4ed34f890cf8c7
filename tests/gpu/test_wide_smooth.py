"""Wide lights through a skylight: the walls of a single-quad room under courtyard.exr, the view's split-light part against traced visibility over each light's own texels."""

import pytest
from helpers import skylight_quads as room

from prt_addon.core.trace import raytrace

pytestmark = pytest.mark.skipif(not raytrace.EMBREE_AVAILABLE, reason="embreex not available")


@pytest.fixture(scope="module")
def courtyard_walls(bpy_module, addon, gpu_ready):
    """The room baked (order 2: the test reads the lights' part, which the bake does not change),
    drawn with courtyard's split lights and with none; the walls sampled (helpers.skylight_quads)."""
    bpy = bpy_module
    scene, _objects, lights, image, sky, _walls = room.baked_views(bpy, "courtyard")
    return lights, room.wall_samples(bpy, scene, image, sky, lights, room.dense_lights(scene, lights))


def test_courtyard_has_wide_lights(courtyard_walls):
    """The case of the walls' patches: wide lights, one of them low (half its samples below the
    floor's horizon), which reach the room only through the skylight."""
    from prt_addon.core.lights.shadow_views import is_wide

    lights, _walls = courtyard_walls
    assert sum(is_wide(light) for light in lights) >= 3
    assert any(is_wide(light) and abs(light.direction[2]) < 0.2 for light in lights)


@pytest.mark.parametrize("wall", ["back", "left"])
def test_skylight_patch_is_smooth_like_the_traced_light(courtyard_walls, wall):
    """Where the skylight's light falls on a wall, the view's split-light part is within 25 % RMS
    of the lights traced over 1024 power cells each (smooth, as Cycles draws it), closer than
    api.shade's 16 rays per light. Before, each wide light's view filtered at most 16 texels of
    its map (10 cm in this 4 m room) where its part of the light throws a 20 to 40 cm penumbra
    (a compact light's 5 cm of its 2048 map), and three wide lights shared 32 maps (groups of two
    samples): patches with straight edges, 0.22 (back) and 0.33 (left) from the traced light."""
    _lights, walls = courtyard_walls
    w = walls[wall]
    assert len(w["view"]) > 1000
    assert w["dense"].mean() > 0.005  # the patch is there
    view = room.relative_rms(w["view"], w["dense"])
    shade = room.relative_rms(w["shade"], w["dense"])
    print(wall, f"view {view:.3f} api.shade {shade:.3f}")
    assert view < 0.25
    assert view < shade


@pytest.mark.parametrize("wall", ["floor", "ceiling"])
def test_grazing_light_does_not_leak_onto_floor_and_ceiling(courtyard_walls, wall):
    """The floor and the ceiling see courtyard's low sun only at grazing angles, where the walls
    block it (traced: ~0): the view's split-light part there is within 2 % of the skylight
    patch's mean on the left wall. Before, a map looking at them edge-on filtered taps past
    their own edge, below their horizon, where nothing casts (lit), and groups of samples
    straddling the horizon had maps looking through them: the floor drew 0.0022 of light
    against 0.0001 traced (7 % of the patch's 0.03)."""
    _lights, walls = courtyard_walls
    w = walls[wall]
    assert len(w["view"]) > 1000
    leak = w["view"].mean() - w["dense"].mean()
    patch = walls["left"]["dense"].mean()
    print(wall, f"view {w['view'].mean():.5f} traced {w['dense'].mean():.5f} patch {patch:.4f}")
    assert abs(leak) < 0.02 * patch


@pytest.mark.parametrize(("wall", "bound"), [("back", 2.8), ("left", 4.3)])
def test_skylight_patch_has_no_streaks(courtyard_walls, wall, bound):
    """Along the wall (one height, 6.4 cm between grid points) the view's split-light part has
    second differences (helpers.skylight_quads.second_differences) within `bound` times those of
    the lights traced over 1024 power cells each: no faint streaks across the patch. With 8 PCF
    taps per wide view, each view's filtered shadow was 8 shifted copies of the skylight's hard
    edge, 128 per light over its 16 views at scattered offsets: steps that bunch into streaks,
    3.7 (back) and 5.1 (left) times the trace's. api.shade's 16 rays per light are rougher still."""
    _lights, walls = courtyard_walls
    w = walls[wall]
    view = room.second_differences(w, "view")
    traced = room.second_differences(w, "dense")
    shade = room.second_differences(w, "shade")
    print(wall, f"view {view / traced:.2f} api.shade {shade / traced:.2f} times the trace's")
    assert traced > 0.0
    assert view < bound * traced
    assert view < shade
