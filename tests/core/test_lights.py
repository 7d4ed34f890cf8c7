"""Analytic lights split off bright world texels: extraction, energy, rotation, discs, shading."""

import numpy as np
import pytest
from helpers.sky import HEIGHT, RADIUS, SUN, WIDTH, cap_solid_angle, disc_fractions, rotation_z, sky_with_discs, unit
from scipy import ndimage

from prt_addon.core.lights import extraction as lights
from prt_addon.core.sh.basis import sh_basis
from prt_addon.core.sh.projection import pixel_directions, pixel_solid_angles, project_equirect

Y0 = 1.0 / (2.0 * np.sqrt(np.pi))


def angle_between(a, b):
    return np.degrees(2.0 * np.arcsin(min(1.0, np.linalg.norm(np.asarray(a) - b) / 2.0)))


@pytest.fixture(scope="module")
def sun_image():
    return sky_with_discs([(SUN, RADIUS, 1000.0)])


def test_renderer_covers_the_analytic_solid_angle():
    fraction = disc_fractions(HEIGHT, WIDTH, SUN, RADIUS)
    covered = (fraction * pixel_solid_angles(HEIGHT, WIDTH)[:, None]).sum()
    assert abs(covered / cap_solid_angle(RADIUS) - 1.0) < 1e-3


def test_one_disc_gives_one_light_with_its_power_direction_and_radius(sun_image):
    threshold = lights.auto_threshold(sun_image)
    assert 1.0 < threshold < 100.0
    residual, found = lights.extract_lights(sun_image)
    assert len(found) == 1
    light = found[0]
    assert angle_between(light.direction, SUN) < 0.2
    expected = (1000.0 - threshold) * cap_solid_angle(RADIUS)
    np.testing.assert_allclose(light.power, expected, rtol=5e-3)
    assert abs(light.angle / RADIUS - 1.0) < 0.2
    assert light.texels > 0
    assert light.solid_angle > 0.9 * cap_solid_angle(RADIUS)
    lum = residual.astype(np.float64) @ lights.LUMA
    assert lum.max() <= threshold * (1 + 1e-6)


def test_rgba_and_rgb_give_the_same_lights(sun_image):
    rgba = np.concatenate([sun_image, np.full(sun_image.shape[:2] + (1,), 0.5, np.float32)], 2)
    residual, found = lights.extract_lights(rgba)
    residual_rgb, found_rgb = lights.extract_lights(sun_image)
    assert residual.shape == sun_image.shape
    assert residual.dtype == np.float32
    np.testing.assert_array_equal(residual, residual_rgb)
    np.testing.assert_array_equal(found[0].power, found_rgb[0].power)


def test_residual_keeps_the_hue_of_clamped_texels():
    image = sky_with_discs([(SUN, RADIUS, (2000.0, 1000.0, 250.0))])
    threshold = 20.0
    residual, found = lights.extract_lights(image, threshold=threshold)
    clamped = image.astype(np.float64) @ lights.LUMA > threshold
    kept = residual[clamped].astype(np.float64)
    np.testing.assert_allclose(kept @ lights.LUMA, threshold, rtol=1e-6)
    np.testing.assert_allclose(kept / kept[:, :1], image[clamped] / image[clamped][:, :1], rtol=1e-5)
    np.testing.assert_array_equal(residual[~clamped], image[~clamped])
    ratio = found[0].power / found[0].power[1]
    np.testing.assert_allclose(ratio, [2.0, 1.0, 0.25], rtol=2e-2)


def test_two_discs_120_degrees_apart_give_two_lights():
    a, b = unit(0.0, 10.0), unit(120.0, 10.0)
    image = sky_with_discs([(a, RADIUS, 1000.0), (b, RADIUS, 600.0)])
    _, found = lights.extract_lights(image)
    assert len(found) == 2
    assert angle_between(found[0].direction, a) < 0.2
    assert angle_between(found[1].direction, b) < 0.2


def test_disc_across_the_seam_is_one_light():
    centre = unit(180.0, 10.0)  # phi = pi is u = 0: the disc is split between both image edges
    image = sky_with_discs([(centre, RADIUS, 1000.0)])
    assert image[:, 0].max() > 500
    assert image[:, -1].max() > 500
    _, found = lights.extract_lights(image)
    assert len(found) == 1
    assert angle_between(found[0].direction, centre) < 0.2
    assert abs(found[0].angle / RADIUS - 1.0) < 0.2


@pytest.mark.parametrize("elevation", [89.5, -89.5])
def test_disc_over_a_pole_is_one_light(elevation):
    centre = unit(40.0, elevation)
    image = sky_with_discs([(centre, RADIUS, 1000.0)])
    _, found = lights.extract_lights(image)
    assert len(found) == 1
    assert angle_between(found[0].direction, centre) < 0.2
    assert abs(found[0].angle / RADIUS - 1.0) < 0.2


def test_texels_of_a_pole_row_are_neighbours():
    image = np.ones((64, 128, 3), np.float32)
    image[-1, [3, 60, 100]] = 1e4  # three separate texels of the top row: one light at the zenith
    image[0, [0, 64]] = 1e4
    _, found = lights.extract_lights(image, threshold=10.0, min_share=0.0)
    assert len(found) == 2
    assert found[0].direction[2] > 0.99
    assert found[1].direction[2] < -0.99


def sphere_components_reference(mask):
    """Partition of the bright texels by scipy's 8-connected labels, then joined across the seam
    and within each pole row (union-find over the few labels)."""
    labels, count = ndimage.label(mask, structure=np.ones((3, 3)))
    parent = list(range(count + 1))

    def find(x):
        while parent[x] != x:
            x = parent[x]
        return x

    def join(a, b):
        if a and b:
            parent[find(a)] = find(b)

    height, width = mask.shape
    for j in range(height):
        for dj in (-1, 0, 1):
            if 0 <= j + dj < height:
                join(labels[j, 0], labels[j + dj, width - 1])
    for row in (0, height - 1):
        present = labels[row][labels[row] > 0]
        for a in present[1:]:
            join(a, present[0])
    return np.array([find(x) for x in range(count + 1)])[labels]


def serpentine(height, width):
    """One long snake of texels (rows joined at alternating ends, away from the seam)."""
    mask = np.zeros((height, width), dtype=bool)
    mask[2:-2:2, 2:-2] = True
    mask[3:-2:4, -3] = True
    mask[5:-2:4, 2] = True
    return mask


@pytest.mark.parametrize("density", [0.02, 0.3, 0.6, "serpentine"])
def test_connected_components_match_scipy_on_random_masks(density):
    rng = np.random.default_rng(3)
    mask = serpentine(60, 96) if density == "serpentine" else rng.random((40, 96)) < density
    flat = np.flatnonzero(mask)
    region, count = lights._connected_components(len(flat), *lights._sphere_neighbour_pairs(flat, *mask.shape))
    reference = sphere_components_reference(mask).ravel()[flat]
    # Same partition: the pairs (ours, reference) are one-to-one.
    pairs = np.unique(np.stack([region, reference]), axis=1)
    assert pairs.shape[1] == count == len(np.unique(reference))


def test_band0_and_full_sh_are_conserved(sun_image):
    original, _ = project_equirect(sun_image, 8)
    residual, found = lights.extract_lights(sun_image)
    split, _ = project_equirect(residual, 8)
    power = sum(light.power for light in found)
    np.testing.assert_allclose(split[0] + power * Y0, original[0], rtol=1e-9)
    excess = sun_image.astype(np.float64) - residual.astype(np.float64)
    excess_sh, _ = project_equirect(excess, 8)
    np.testing.assert_allclose(split + excess_sh, original, rtol=0, atol=1e-9 * original[0].max())
    # The point light power * y(s) against the excess's true SH at order 8 (a 2 degree disc).
    point = sh_basis(found[0].direction[None], 8)[0][:, None] * found[0].power[None]
    error = np.linalg.norm(point - excess_sh) / np.linalg.norm(excess_sh)
    print(f"point-light approximation of a 2 degree disc at order 8: {error:.2e} relative")
    assert error < 1e-2


@pytest.mark.parametrize("colour", [(1.0, 1.0, 1.0), (0.3, 0.5, 0.9), (0.0, 0.0, 0.0), (7e3, 7e3, 7e3)])
def test_uniform_or_one_colour_image_gives_no_lights(colour):
    image = np.broadcast_to(np.asarray(colour, np.float32), (HEIGHT, WIDTH, 3)).copy()
    residual, found = lights.extract_lights(image)
    assert found == []
    np.testing.assert_array_equal(residual, image)


def test_max_lights_caps_the_count_and_returned_regions_conserve_energy():
    discs = [(unit(45.0 * k, 15.0 * (k % 3)), RADIUS, 300.0 * (k + 1)) for k in range(5)]
    image = sky_with_discs(discs)
    original, _ = project_equirect(image, 3)
    _, all_found = lights.extract_lights(image, max_lights=8)
    assert len(all_found) == 5
    residual, found = lights.extract_lights(image, max_lights=2)
    assert len(found) == 2
    for light, disc in zip(found, discs[::-1][:2], strict=True):
        assert angle_between(light.direction, disc[0]) < 0.2
    split, _ = project_equirect(residual, 3)
    power = sum(light.power for light in found)
    np.testing.assert_allclose(split[0] + power * Y0, original[0], rtol=1e-9)
    for centre, _, _ in discs[:3]:  # the weaker discs are back in the residual untouched
        row, col = np.unravel_index(np.argmax(pixel_directions(HEIGHT, WIDTH) @ centre), (HEIGHT, WIDTH))
        np.testing.assert_array_equal(residual[row, col], image[row, col])
    residual, found = lights.extract_lights(image, max_lights=0)
    assert found == []
    np.testing.assert_array_equal(residual, image)


def test_min_share_drops_negligible_regions_into_the_residual():
    image = sky_with_discs([(SUN, RADIUS, 1000.0), (unit(-90.0, 0.0), np.radians(0.5), 100.0)])
    _, found = lights.extract_lights(image)
    assert len(found) == 1
    _, found = lights.extract_lights(image, min_share=0.0)
    assert len(found) == 2


@pytest.mark.parametrize(
    "kwargs",
    [
        {"threshold": float("nan")},
        {"threshold": -1.0},
        {"threshold": float("inf")},
        {"threshold": "10"},
        {"max_lights": 9},
        {"max_lights": -1},
        {"max_lights": 2.5},
        {"max_lights": True},
        {"min_share": -0.1},
        {"min_share": float("nan")},
    ],
)
def test_bad_arguments_raise_value_error(kwargs):
    (name,) = kwargs
    with pytest.raises(ValueError, match=f"^{name} must be"):
        lights.extract_lights(np.ones((8, 16, 3), np.float32), **kwargs)


def test_bad_pixels_follow_the_projection_policy(sun_image):
    image = sun_image.copy()
    image[10, 10] = np.nan
    image[20, 20, 1] = np.inf
    image[30, 30, 0] = -5.0
    residual, found = lights.extract_lights(image)
    assert len(found) == 1
    assert np.isnan(residual[10, 10]).all()
    assert np.isinf(residual[20, 20, 1])
    original, _ = project_equirect(image, 1)
    split, _ = project_equirect(residual, 1)
    np.testing.assert_allclose(split[0] + found[0].power * Y0, original[0], rtol=1e-9)


def test_rotating_lights_matches_rotating_the_image():
    image = sky_with_discs([(unit(30.0, 40.0), RADIUS, 1000.0), (unit(-100.0, -20.0), RADIUS, 500.0)])
    rolled = np.roll(image, WIDTH // 4, axis=1)
    # Rolling the columns by W/4 moves what was at azimuth phi to phi - 90 degrees.
    rotation = rotation_z(-np.pi / 2)
    directions = pixel_directions(HEIGHT, WIDTH)
    np.testing.assert_allclose(np.roll(directions, WIDTH // 4, axis=1) @ rotation.T, directions, atol=1e-12)
    _, found = lights.extract_lights(image)
    _, found_rolled = lights.extract_lights(rolled)
    rotated = lights.rotate_lights(found, rotation)
    assert len(rotated) == len(found_rolled) == 2
    for a, b in zip(rotated, found_rolled, strict=True):
        np.testing.assert_allclose(a.direction, b.direction, atol=1e-9)
        np.testing.assert_allclose(a.power, b.power, rtol=1e-9)
        assert abs(a.angle - b.angle) < 1e-9


def test_lights_array_round_trip(sun_image):
    _, found = lights.extract_lights(sun_image)
    values = lights.lights_to_array(found)
    assert isinstance(values, list)
    assert len(values) == 7 * len(found)
    back = lights.lights_from_array(values)
    for a, b in zip(found, back, strict=True):
        np.testing.assert_allclose(a.direction, b.direction, atol=1e-15)
        np.testing.assert_array_equal(a.power, b.power)
        assert a.angle == b.angle
    assert lights.lights_from_array([]) == []
    assert lights.lights_to_array([]) == []
    with pytest.raises(ValueError, match=r"stored lights must be finite, 7 floats per light \(got 6 values\)"):
        lights.lights_from_array(values[:-1])
    with pytest.raises(ValueError, match=r"stored lights must be finite, 7 floats per light \(got 7 values\)"):
        lights.lights_from_array([np.nan] * 7)
