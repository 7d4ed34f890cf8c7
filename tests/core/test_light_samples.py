"""Wide lights as power-weighted samples of their own texels: split, shading, visibility, storage."""

import numpy as np
import pytest
from helpers.sky import HalfPlane, rotation_z, sky_with_discs, unit

from prt_addon.core.lights import extraction as lights, samples as light_samples, visibility
from prt_addon.core.sh.projection import pixel_directions, pixel_solid_angles

HEIGHT, WIDTH = 256, 512
WIDE = unit(20.0, 12.0)
WIDE_RADIUS = np.radians(30.0)  # a cap of 30 degrees: it straddles the horizon of many normals


@pytest.fixture(scope="module")
def wide_image():
    return sky_with_discs([(WIDE, WIDE_RADIUS, 50.0)], height=HEIGHT, width=WIDTH)


def texel_excess(image, residual):
    """(directions (N, 3), RGB power (N, 3)) of the texels' excess, one node per texel."""
    power = (image.astype(np.float64) - residual) * pixel_solid_angles(*image.shape[:2])[:, None, None]
    dirs = pixel_directions(*image.shape[:2]).reshape(-1, 3)
    power = power.reshape(-1, 3)
    keep = power.max(axis=1) > 0.0
    return dirs[keep], power[keep]


def random_normals(count, seed):
    normals = np.random.default_rng(seed).normal(size=(count, 3))
    return normals / np.linalg.norm(normals, axis=1, keepdims=True)


def test_region_samples_split_the_power_evenly_inside_the_region():
    rng = np.random.default_rng(2)
    centre = unit(-40.0, 25.0)
    dirs = visibility.disc_directions(centre, np.radians(15.0), 4000)  # uniform over a 15 degree cap
    weights = rng.uniform(0.5, 1.5, len(dirs))
    samples, w = light_samples.region_samples(dirs * weights[:, None], weights, 16)
    assert samples.shape == (16, 3)
    assert w.shape == (16,)
    np.testing.assert_allclose(w.sum(), 1.0, rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(samples, axis=1), 1.0, rtol=1e-12)
    assert np.all(np.abs(w - 1.0 / 16) < 0.2 / 16)  # halves of equal power, each within a texel's weight
    assert np.all(samples @ centre > np.cos(np.radians(15.0)))
    mean = w @ samples
    assert np.degrees(np.arccos(min(1.0, mean @ centre / np.linalg.norm(mean)))) < 0.5
    few, few_w = light_samples.region_samples(dirs[:5] * weights[:5, None], weights[:5], 16)
    assert len(few) == 5  # one sample per texel when there are fewer texels than samples
    np.testing.assert_allclose(np.sort(few_w), np.sort(weights[:5] / weights[:5].sum()), rtol=1e-12)
    with pytest.raises(ValueError, match="a light's region has no power"):
        light_samples.region_samples(dirs[:3], np.zeros(3))


def test_wide_light_shading_matches_the_texel_sum_at_every_normal(wide_image):
    """Unoccluded, P / pi sum_j w_j max(0, n . s_j) against the excess summed texel by texel with
    max(0, n . w) / pi, for normals all round (the cap half below the horizon of many)."""
    residual, found = lights.extract_lights(wide_image, threshold=10.0)
    assert len(found) == 1
    assert len(found[0].samples) == light_samples.SAMPLES_PER_LIGHT
    dirs, power = texel_excess(wide_image, residual)
    normals = random_normals(400, 7)
    brute = np.maximum(0.0, normals @ dirs.T) / np.pi @ power
    scale = found[0].power[0] / np.pi  # a facing surface's value
    error = np.abs(visibility.light_irradiance(normals, found) - brute).max() / scale
    _, disc = lights.extract_lights(wide_image, threshold=10.0, samples=0)
    disc_error = np.abs(visibility.light_irradiance(normals, disc) - brute).max() / scale
    print(f"30 degree light, max error / facing value: samples {error:.4f}, disc {disc_error:.4f}")
    assert error < 0.01
    assert disc_error > 3.0 * error


def test_sampled_visibility_converges_to_the_traced_texels(wide_image):
    """A half-plane (z = 1, y > 0) over points at several y hides part of a 30 degree light near
    the zenith; the truth traces every excess texel: sum P_t max(0, n . w) V_t / sum P_t max(0, n . w)."""
    centre = unit(0.0, 80.0)
    image = sky_with_discs([(centre, WIDE_RADIUS, 50.0)], height=HEIGHT, width=WIDTH)
    y0 = np.array([-1.0, -0.4, -0.15, 0.0, 0.15, 0.4, 1.0])
    points = np.stack([np.zeros_like(y0), y0, np.zeros_like(y0)], axis=1)
    normals = np.tile([0.0, 0.0, 1.0], (len(y0), 1))
    residual, _ = lights.extract_lights(image, threshold=10.0, samples=0)
    dirs, power = texel_excess(image, residual)
    weight = np.maximum(0.0, dirs[:, 2]) * (power @ lights.LUMA)
    free = np.stack(
        [~HalfPlane().occluded(np.tile(p, (len(dirs), 1)).astype(np.float32), dirs.astype(np.float32)) for p in points]
    )
    truth = free @ weight / weight.sum()
    assert truth[0] > 0.9
    assert truth[-1] < 0.1
    # The light's excess texels as 16 or 256 samples: 16 rays resolve an edge to about 1/16.
    for count, tolerance in ((16, 0.07), (256, 0.015)):
        _, found = lights.extract_lights(image, threshold=10.0, samples=count)
        seen = visibility.light_visibility(points, normals, found, HalfPlane(), offset=1e-6)[:, 0]
        print(f"{count} samples: largest visibility error {np.abs(seen - truth).max():.4f}")
        np.testing.assert_allclose(seen, truth, atol=tolerance)


def test_samples_round_trip_and_old_storage_loads_as_discs(wide_image):
    _, found = lights.extract_lights(sky_with_discs([(WIDE, WIDE_RADIUS, 50.0), (unit(200, 40), 0.02, 1e4)]), 10.0)
    assert len(found) == 2
    values, samples = lights.lights_to_array(found), light_samples.samples_to_array(found)
    back = lights.lights_from_array(values, samples)
    for a, b in zip(found, back, strict=True):
        np.testing.assert_allclose(a.samples, b.samples, atol=1e-15)
        np.testing.assert_allclose(a.weights, b.weights, rtol=1e-14)
    old = lights.lights_from_array(values)  # a file stored before samples existed
    assert all(light.samples is None and light.weights is None for light in old)
    mixed = light_samples.samples_to_array([found[0], old[1]])
    assert lights.lights_from_array(values, mixed)[1].samples is None
    for bad, message in (
        (samples[:-1], "stored light samples are truncated"),
        (samples + [0.0], "stored light samples hold more values than their lights"),
        ([1.5] + samples[1:], "stored light samples: a count is missing or not a whole number"),
        ([np.nan] * len(samples), "stored light samples must be finite"),
    ):
        with pytest.raises(ValueError, match=message):
            lights.lights_from_array(values, bad)
    for index, message in (  # the first light's shadow angle, its first sample's weight
        (1, "stored light samples: a shadow angle is missing or negative"),
        (5, "a stored light sample has a zero direction or a negative weight"),
    ):
        negative = list(samples)
        negative[index] = -1.0
        with pytest.raises(ValueError, match=message):
            lights.lights_from_array(values, negative)
    assert [b.shadow_angle for b in back] == pytest.approx([light_samples.shadow_angle(a) for a in found], rel=1e-14)
    assert [light_samples.shadow_angle(b) for b in old] == [b.angle for b in old]
    with pytest.raises(ValueError, match="samples must be an integer >= 0, got -1"):
        lights.extract_lights(wide_image, samples=-1)


def test_rotated_samples_match_the_samples_of_the_rotated_image():
    """Rolling the columns by W/4 is the rotation by -90 degrees about Z (an uneven region: two
    overlapping caps). Texels whose projections on a cell's axis tie to rounding may fall on
    either side of a median, so the two splits agree to about a texel's share of the power."""
    image = sky_with_discs(
        [(unit(30.0, 20.0), np.radians(12.0), 40.0), (unit(42.0, 28.0), np.radians(6.0), 90.0)],
        height=HEIGHT,
        width=WIDTH,
    )
    _, found = lights.extract_lights(image, threshold=5.0)
    _, found_rolled = lights.extract_lights(np.roll(image, WIDTH // 4, axis=1), threshold=5.0)
    rotated = lights.rotate_lights(found, rotation_z(-np.pi / 2))
    normals = random_normals(300, 11)
    np.testing.assert_allclose(
        visibility.light_cosines(normals, rotated), visibility.light_cosines(normals, found_rolled), atol=1e-3
    )
    np.testing.assert_allclose(rotated[0].samples, found[0].samples @ rotation_z(-np.pi / 2).T, atol=1e-15)
    np.testing.assert_allclose(rotated[0].direction, found_rolled[0].direction, atol=1e-9)


@pytest.mark.parametrize("degrees", [2.0, 10.0, 30.0])
def test_shadow_angle_of_a_uniform_cap_is_its_radius(degrees):
    image = sky_with_discs([(WIDE, np.radians(degrees), 50.0)], height=HEIGHT, width=WIDTH)
    _, found = lights.extract_lights(image, threshold=10.0)
    assert light_samples.shadow_angle(found[0]) == pytest.approx(np.radians(degrees), rel=0.04)
    assert light_samples.shadow_angle(found[0]) <= found[0].angle


def test_shadow_angle_of_a_sun_in_its_halo_is_the_sun():
    """A 0.5 degree sun holding most of the power inside a 10 degree halo: the moment radius is
    the halo's spread, the power-median radius about the sun's (the viewport's penumbra)."""
    sun = np.radians(0.5)
    image = sky_with_discs([(WIDE, np.radians(10.0), 5.0), (unit(22.0, 13.0), sun, 5e4)])
    _, found = lights.extract_lights(image, threshold=2.0)
    assert len(found) == 1
    assert found[0].angle > 3.0 * sun
    assert light_samples.shadow_angle(found[0]) == pytest.approx(sun, rel=0.2)
