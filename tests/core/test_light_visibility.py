"""A light's shading: rays over its disc, their visibility against exact fractions, E/pi under it."""

import numpy as np
import pytest
from helpers.sky import HEIGHT, RADIUS, SUN, WIDTH, HalfPlane, cap_solid_angle, sky_with_discs, unit
from scipy import integrate

from prt_addon.core.lights import extraction as lights, visibility as light_vis
from prt_addon.core.sh.projection import pixel_directions, pixel_solid_angles
from prt_addon.core.trace import raytrace


@pytest.fixture(scope="module")
def sun_image():
    return sky_with_discs([(SUN, RADIUS, 1000.0)])


@pytest.mark.parametrize("count", [1, 2, 7, 16, 1000])
def test_disc_directions_fill_the_cap_around_the_centre(count):
    centre = unit(-70.0, 35.0)
    angle = np.radians(3.0)
    dirs = light_vis.disc_directions(centre, angle, count)
    assert dirs.shape == (count, 3)
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=1), 1.0, atol=1e-14)
    assert np.all(dirs @ centre >= np.cos(angle) - 1e-14)
    mean = dirs.mean(axis=0)
    np.testing.assert_allclose(mean / np.linalg.norm(mean), centre, atol=1e-14)
    if count == 1:
        np.testing.assert_allclose(dirs[0], centre, atol=1e-15)
    if count == 1000:  # uniform in solid angle: half of them inside the half-area cap
        inner = dirs @ centre >= 1.0 - 0.5 * (1.0 - np.cos(angle))
        assert abs(inner.mean() - 0.5) <= 1.0 / count


def half_plane_free_fraction(y0, angle):
    """Seen from (0, y0, 0) the half-plane hides the zenith cap's directions with
    tan(theta) sin(phi) > -y0; the phi measure of sin(phi) > t is pi - 2 asin(t)."""

    def hidden(theta):
        t = np.clip(-y0 / np.tan(theta), -1.0, 1.0) if theta > 0 else np.sign(-y0)
        return np.sin(theta) * (np.pi - 2.0 * np.arcsin(t))

    value, _ = integrate.quad(hidden, 0.0, angle, limit=200, points=[abs(np.arctan(y0))])
    return 1.0 - value / cap_solid_angle(angle)


def test_light_visibility_of_a_partly_hidden_disc():
    angle = np.radians(5.0)
    light = lights.Light(direction=[0.0, 0.0, 1.0], power=[1.0, 1.0, 1.0], angle=angle)
    y0 = np.array([-0.2, -0.05, -0.02, 0.0, 0.03, 0.07, 0.2])
    points = np.stack([np.zeros_like(y0), y0, np.zeros_like(y0)], axis=1)
    normals = np.tile([0.0, 0.0, 1.0], (len(y0), 1))
    expected = np.array([half_plane_free_fraction(y, angle) for y in y0])
    np.testing.assert_allclose(expected[[0, 3, -1]], [1.0, 0.5, 0.0], atol=1e-12)
    # A straight edge across N stratified samples: error ~ N^(-3/4) (0.016 at 256, 0.006 at 1024).
    for rays, tolerance in ((256, 0.03), (1024, 0.012)):
        seen = light_vis.light_visibility(points, normals, [light], HalfPlane(), rays_per_light=rays)
        assert seen.shape == (len(y0), 1)
        np.testing.assert_allclose(seen[:, 0], expected, atol=tolerance)


class Nothing:
    def occluded(self, origins, directions):
        return np.zeros(len(origins), dtype=bool)


def test_light_visibility_at_the_horizon():
    angle = np.radians(6.0)
    grazing = lights.Light(direction=unit(0.0, 2.0), power=[1.0] * 3, angle=angle)
    below = lights.Light(direction=unit(0.0, -1.0), power=[1.0] * 3, angle=angle)
    sharp = lights.Light(direction=unit(0.0, 30.0), power=[1.0] * 3, angle=0.0)
    seen = light_vis.light_visibility(
        np.zeros((1, 3)), [[0.0, 0.0, 1.0]], [grazing, below, sharp], Nothing(), rays_per_light=512
    )
    # Part of the grazing disc is below the tangent plane: the free fraction is the cap's share
    # above it, estimated independently with random points on the cap.
    rng = np.random.default_rng(1)
    cos_theta = 1.0 - rng.random(200_000) * (1.0 - np.cos(angle))
    phi = rng.random(200_000) * 2.0 * np.pi
    sin_theta = np.sqrt(1.0 - cos_theta**2)
    elevation = np.radians(2.0)  # z of a cap point about the axis (cos e, 0, sin e)
    z = cos_theta * np.sin(elevation) + sin_theta * np.cos(phi) * np.cos(elevation)
    assert abs(seen[0, 0] - (z > 0).mean()) < 0.02
    assert seen[0, 1] == 0.0
    assert seen[0, 2] == 1.0


def test_light_irradiance_closed_form_and_texel_sum(sun_image):
    residual, found = lights.extract_lights(sun_image, samples=0)  # the disc model
    rng = np.random.default_rng(5)
    normals = rng.normal(size=(200, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    shown = light_vis.light_irradiance(normals, found)
    closed = found[0].power[None] / np.pi * np.maximum(0.0, normals @ found[0].direction)[:, None]
    np.testing.assert_allclose(shown, closed, rtol=1e-12, atol=1e-12)
    visibility = rng.random((200, 1))
    np.testing.assert_allclose(
        light_vis.light_irradiance(normals, found, visibility), closed * visibility, rtol=1e-12, atol=1e-12
    )
    # Same unit as the transfer max(0, n . w) / pi: the excess summed texel by texel.
    excess = (sun_image.astype(np.float64) - residual) * pixel_solid_angles(HEIGHT, WIDTH)[:, None, None]
    dirs = pixel_directions(HEIGHT, WIDTH).reshape(-1, 3)
    facing = normals @ found[0].direction > 0.2
    brute = np.maximum(0.0, normals[facing] @ dirs.T) / np.pi @ excess.reshape(-1, 3)
    np.testing.assert_allclose(shown[facing], brute, rtol=2e-3)
    assert np.all(light_vis.light_irradiance(np.zeros((3, 3)), found) == 0.0)
    assert light_vis.light_irradiance(normals, []).shape == (200, 3)


class _Recorder:
    """An occluder that blocks nothing and keeps the origins it was asked about."""

    def __init__(self):
        self.origins = []

    def occluded(self, origins, dirs):
        self.origins.append(np.array(origins))
        return np.zeros(len(origins), dtype=bool)


def test_light_visibility_moves_origins_along_the_contact_tangents():
    from prt_addon.core.transfer.contact import inward_tangents

    # The foot of a wall (x = 0, facing +x, one quad) standing on a floor: its contact tangent
    # points up the wall, and the rays start there, not in the floor's plane.
    wall = np.array([[0.0, -1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 1.0, 2.0], [0.0, -1.0, 2.0]])
    triangles = np.array([[0, 1, 2], [0, 2, 3]])
    points = wall[:2]
    normals = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    tangents = inward_tangents(points, normals, wall, triangles, point_vertex=[0, 1])
    sun = lights.Light(direction=unit(0.0, 10.0), power=np.ones(3), angle=0.0)
    recorder = _Recorder()
    light_vis.light_visibility(points, normals, [sun], recorder, offset=0.01, tangents=tangents)
    np.testing.assert_allclose(recorder.origins[0], points + 0.01 * (normals + tangents), rtol=1e-6)
    assert np.all(recorder.origins[0][:, 2] > 0.005)  # above the floor
    recorder = _Recorder()
    light_vis.light_visibility(points, normals, [sun], recorder, offset=0.01)
    np.testing.assert_allclose(recorder.origins[0], points + 0.01 * normals, rtol=1e-6)
    with pytest.raises(ValueError, match="tangents"):
        light_vis.light_visibility(points, normals, [sun], recorder, offset=0.01, tangents=tangents[:1])


@pytest.mark.skipif(not raytrace.EMBREE_AVAILABLE, reason="embreex not installed")
def test_light_below_the_floor_is_hidden_from_a_wall_foot():
    """A light 10 degrees below the horizon, seen from the foot of a wall on a floor: the floor
    hides it (Cycles: 0). From origins moved along the tangent the floor is hit at t ~ offset /
    sin 10 degrees; a light 10 degrees above stays seen."""
    from prt_addon.core.transfer.contact import inward_tangents

    floor = np.array([[-5.0, -5.0, 0.0], [5.0, -5.0, 0.0], [5.0, 5.0, 0.0], [-5.0, 5.0, 0.0]])
    y = np.linspace(-0.9, 0.9, 7)
    wall = np.r_[np.c_[np.zeros_like(y), y, np.zeros_like(y)], np.c_[np.zeros_like(y), y, np.full_like(y, 2.0)]]
    i = np.arange(len(y) - 1)
    k = len(y)
    wall_tris = np.r_[np.c_[i, i + 1, k + i + 1], np.c_[i, k + i + 1, k + i]]  # facing +x
    quads = np.array([[0, 1, 2], [0, 2, 3]])
    occluder = raytrace.EmbreeOccluder(
        np.r_[floor, wall].astype(np.float32), np.r_[quads, wall_tris + 4].astype(np.int32)
    )
    points = wall[:k]
    normals = np.tile([1.0, 0.0, 0.0], (k, 1))
    tangents = inward_tangents(points, normals, wall, wall_tris)
    assert np.all(tangents[:, 2] > 0.7)  # up the wall (diagonally at its two ends)
    np.testing.assert_allclose(tangents[:, 0], 0.0, atol=1e-6)
    below = lights.Light(direction=unit(0.0, -10.0), power=np.ones(3), angle=0.0)
    above = lights.Light(direction=unit(0.0, 10.0), power=np.ones(3), angle=0.0)
    seen = light_vis.light_visibility(points, normals, [below, above], occluder, offset=1e-3, tangents=tangents)
    np.testing.assert_array_equal(seen, np.tile([0.0, 1.0], (k, 1)))
