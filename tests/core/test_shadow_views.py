"""The viewport's shadow views of the split lights (core.lights.shadow_views): which lights get several
maps, how their samples are shared out, and that the shading they stand for is the light's."""

import numpy as np
import pytest

from prt_addon.core.lights import samples as light_samples
from prt_addon.core.lights.extraction import Light
from prt_addon.core.lights.shadow_views import MAX_WIDE_VIEWS, WIDE_ANGLE, shadow_views


def spread_light(degrees, count=16, centre=(0.2, -0.4, 1.0), seed=0):
    """A light whose `count` samples spread over a cap of about `degrees` radius."""
    rng = np.random.default_rng(seed)
    z = np.asarray(centre, dtype=np.float64) / np.linalg.norm(centre)
    tilt = np.radians(degrees) * np.sqrt(rng.uniform(size=count))
    phi = rng.uniform(0.0, 2.0 * np.pi, size=count)
    x = np.cross([1.0, 0.0, 0.0], z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    dirs = np.cos(tilt)[:, None] * z + np.sin(tilt)[:, None] * (np.cos(phi)[:, None] * x + np.sin(phi)[:, None] * y)
    weights = rng.uniform(0.5, 1.5, size=count)
    weights /= weights.sum()
    return Light(
        z, (1.0, 2.0, 3.0), np.radians(degrees), samples=dirs, weights=weights, shadow_angle=np.radians(degrees)
    )


def test_a_sun_and_a_disc_light_get_one_view_each():
    sun = spread_light(0.5)
    disc = Light((0.0, 0.0, 2.0), (1.0, 1.0, 1.0), 0.3)
    views = shadow_views([sun, disc])
    assert [(v.light, v.wide) for v in views] == [(0, False), (1, False)]
    np.testing.assert_array_equal(views[0].samples, sun.samples / np.linalg.norm(sun.samples, axis=1, keepdims=True))
    np.testing.assert_allclose(views[0].weights, sun.weights, rtol=1e-15)
    np.testing.assert_allclose(views[0].direction, sun.direction / np.linalg.norm(sun.direction))
    np.testing.assert_array_equal(views[1].samples, [[0.0, 0.0, 1.0]])
    assert views[1].weights.tolist() == [1.0]
    assert views[1].angle == 0.3
    assert views[0].angle == light_samples.shadow_angle(sun)


def test_the_wide_angle_is_the_boundary():
    below = spread_light(np.degrees(WIDE_ANGLE) * 0.99)
    above = spread_light(np.degrees(WIDE_ANGLE) * 1.01)
    assert len(shadow_views([below])) == 1
    assert len(shadow_views([above])) == 16


def test_a_wide_light_gets_one_view_per_sample():
    light = spread_light(30.0)
    views = shadow_views([light])
    assert len(views) == 16
    assert all(v.wide and v.light == 0 for v in views)
    dirs = np.array([v.samples[0] for v in views])
    order = np.lexsort(dirs.T)
    want = light.samples / np.linalg.norm(light.samples, axis=1, keepdims=True)
    np.testing.assert_allclose(dirs[order], want[np.lexsort(want.T)], rtol=1e-14)
    for view in views:
        np.testing.assert_allclose(view.direction, view.samples[0], rtol=1e-14)
        assert view.angle == pytest.approx(np.radians(30.0) / 4.0, rel=1e-12)  # sqrt(1 / 16)
    assert sum(v.weights.sum() for v in views) == pytest.approx(1.0, rel=1e-14)


@pytest.mark.parametrize("wide", [1, 2, 3, 5, 8])
def test_wide_lights_share_the_budget_and_keep_their_cosine(wide):
    """With several wide lights each gets MAX_WIDE_VIEWS // wide groups (at most its samples):
    every sample is in exactly one view of its light, so sum over views of sum_j w_j max(0, n.s_j)
    is the light's own cosine term for any normal; a group's direction is its weighted mean and its
    filter radius sqrt(m / k) of the light's shadow angle."""
    lights = [spread_light(20.0 + 5 * i, centre=(np.cos(i), np.sin(i), 0.5), seed=i) for i in range(wide)]
    lights.append(spread_light(1.0, seed=99))  # and a compact one, which keeps one view
    views = shadow_views(lights)
    groups = min(16, MAX_WIDE_VIEWS // wide)
    assert sum(v.wide for v in views) == wide * groups <= MAX_WIDE_VIEWS
    normals = np.random.default_rng(7).normal(size=(50, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    for index, light in enumerate(lights):
        mine = [v for v in views if v.light == index]
        assert len(mine) == (groups if index < wide else 1)
        got = sum(np.maximum(normals @ v.samples.T, 0.0) @ v.weights for v in mine)
        want = np.maximum(normals @ light.samples.T, 0.0) @ light.weights
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)
        assert sum(len(v.weights) for v in mine) == len(light.weights)
        for v in mine if index < wide else []:
            mean = v.weights @ v.samples
            np.testing.assert_allclose(v.direction, mean / np.linalg.norm(mean), rtol=1e-12)
            share = np.sqrt(len(v.weights) / 16)
            assert v.angle == pytest.approx(light_samples.shadow_angle(light) * share, rel=1e-12)


def test_power_cells_keep_the_region_samples():
    """region_samples is power_cells' cells, each one's normalised moment and power share."""
    rng = np.random.default_rng(3)
    dirs = rng.normal(size=(500, 3)) + [0.0, 0.0, 4.0]
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    weights = rng.uniform(size=500)
    samples, sample_weights = light_samples.region_samples(dirs * weights[:, None], weights)
    cells = light_samples.power_cells(dirs, weights, 16)
    assert sorted(np.concatenate(cells).tolist()) == list(range(500))
    moments = np.array([(dirs[c] * weights[c, None]).sum(axis=0) for c in cells])
    np.testing.assert_allclose(samples, moments / np.linalg.norm(moments, axis=1, keepdims=True), rtol=1e-12)
    np.testing.assert_allclose(sample_weights, [weights[c].sum() / weights.sum() for c in cells], rtol=1e-12)
    # Cells of about equal power: a median split halves a cell's weight up to one direction's.
    assert np.ptp([weights[c].sum() for c in cells]) < 4 * weights.max()


def test_the_wide_maps_follow_the_scenes_triangles():
    """WIDE_TRIANGLES // triangles maps in all, between 1 and MAX_WIDE_VIEWS; shared by the wide
    lights, each keeping at least one (then it is drawn as a compact light is, from one map)."""
    from prt_addon.core.lights.shadow_views import WIDE_TRIANGLES, wide_view_budget

    assert wide_view_budget(1) == MAX_WIDE_VIEWS
    assert wide_view_budget(WIDE_TRIANGLES // MAX_WIDE_VIEWS) == MAX_WIDE_VIEWS
    assert wide_view_budget(WIDE_TRIANGLES // 4) == 4
    assert wide_view_budget(WIDE_TRIANGLES // 4 + 1) == 3
    assert wide_view_budget(10 * WIDE_TRIANGLES) == 1
    lights = [spread_light(30.0, seed=1), spread_light(25.0, centre=(1.0, 0.0, 0.3), seed=2)]
    assert [len(shadow_views(lights, max_wide_views=b)) for b in (32, 8, 4, 3, 1)] == [32, 8, 4, 2, 2]
    single = shadow_views(lights[:1], max_wide_views=1)[0]
    assert single.wide
    assert len(single.weights) == 16
    assert single.angle == pytest.approx(light_samples.shadow_angle(lights[0]), rel=1e-12)
