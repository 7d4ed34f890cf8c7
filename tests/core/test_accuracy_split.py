"""The accuracy report's brute-force reference (benchmarks/accuracy_split.py) against closed forms:
its nodes keep the image's power, and a point under a uniform sky, a sun or half a sky gets the
exact E/pi. Pure numpy: the occluders are stand-ins of the core.trace.raytrace protocol."""

import numpy as np
import pytest

from benchmarks.accuracy_split import brute_force, pack, quadrature_nodes, unpack
from prt_addon.core.sh.projection import pixel_directions, pixel_solid_angles

HEIGHT, WIDTH = 128, 256


class Nothing:
    def occluded(self, origins, directions):
        return np.zeros(len(origins), dtype=bool)


class HalfSpace:
    """Blocks every ray going towards +x (a wall along the plane x = 0, infinitely high)."""

    def occluded(self, origins, directions):
        return np.asarray(directions)[:, 0] > 0.0


def points(normals, occluder):
    normals = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    return np.zeros_like(normals), normals, np.zeros_like(normals), occluder


def sun_sky(sky=0.5, sun=2e4, elevation=30.0, azimuth=20.0):
    """A uniform sky with one very bright texel; returns the image and the sun's direction and
    radiance x solid angle (both from the texel's own centre and exact solid angle)."""
    image = np.full((HEIGHT, WIDTH, 3), sky)
    dirs = pixel_directions(HEIGHT, WIDTH)
    target = np.array(
        [
            np.cos(np.radians(elevation)) * np.cos(np.radians(azimuth)),
            np.cos(np.radians(elevation)) * np.sin(np.radians(azimuth)),
            np.sin(np.radians(elevation)),
        ]
    )
    row, col = np.unravel_index(np.argmax(dirs @ target), (HEIGHT, WIDTH))
    image[row, col] = sun
    return image, dirs[row, col], (sun - sky) * pixel_solid_angles(HEIGHT, WIDTH)[row]


@pytest.mark.parametrize("coarse", [(32, 64), (16, 32)])
def test_nodes_keep_the_power_and_the_brightest_texels(coarse):
    rng = np.random.default_rng(1)
    image = rng.uniform(0.0, 2.0, size=(HEIGHT, WIDTH, 3))
    image[40, 50] = (300.0, 200.0, 100.0)
    directions, power = quadrature_nodes(image, coarse, bright=10)
    solid = pixel_solid_angles(HEIGHT, WIDTH)[:, None, None]
    np.testing.assert_allclose(power.sum(axis=0), (image * solid).sum(axis=(0, 1)), rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(directions, axis=1), 1.0, atol=1e-12)
    assert len(directions) == 10 + coarse[0] * coarse[1]
    sun = pixel_directions(HEIGHT, WIDTH)[40, 50]
    assert np.min(np.linalg.norm(directions[:10] - sun, axis=1)) < 1e-12  # kept at full resolution


def test_uniform_sky_gives_its_radiance_on_any_unoccluded_surface():
    image = np.full((HEIGHT, WIDTH, 3), (0.2, 0.5, 1.0))
    normals = [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [0.6, 0.0, 0.8], [1.0, 0.0, 0.0]]
    out = brute_force(points(normals, Nothing()), quadrature_nodes(image, (32, 64), bright=64))
    np.testing.assert_allclose(out, np.tile([0.2, 0.5, 1.0], (4, 1)), rtol=2e-3)  # E/pi = L


def test_sun_adds_power_times_cosine_over_pi():
    image, sun, power = sun_sky()
    normals = np.array([[0.0, 0.0, 1.0], [0.8, 0.0, 0.6], [-1.0, 0.0, 0.0]])
    out = brute_force(points(normals, Nothing()), quadrature_nodes(image, (32, 64), bright=16))
    expected = 0.5 + power * np.maximum(normals @ sun, 0.0) / np.pi
    np.testing.assert_allclose(out[:, 0], expected, rtol=2e-3)


def test_half_the_sky_blocked_halves_an_upward_surface():
    image = np.full((HEIGHT, WIDTH, 3), 1.0)
    out = brute_force(points([[0.0, 0.0, 1.0]], HalfSpace()), quadrature_nodes(image, (32, 64), bright=64))
    np.testing.assert_allclose(out, 0.5, rtol=5e-3)  # the cosine lobe is symmetric in x


def test_references_round_trip_through_the_json_cache():
    values = np.random.default_rng(2).normal(size=(17, 3))
    np.testing.assert_allclose(unpack(pack(values)), values.astype(np.float32), rtol=0)
