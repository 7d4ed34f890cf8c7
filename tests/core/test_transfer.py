"""Transfer projection (prt_addon.core.transfer.quadrature) against closed forms: values, error estimate, local frame.

The analytic occluders (plane, cup) are in tests/helpers/occluders.py, shared with tests/core/test_transfer_tracing.py.
Pure numpy (+ embreex when installed), no bpy."""

import numpy as np
import pytest
from helpers.occluders import CupOccluder, PlaneOccluder, WallOccluder
from helpers.sampling import random_directions

from prt_addon.core.sh import analytic, basis as sh, frames
from prt_addon.core.sh.analytic import _zonal_integral
from prt_addon.core.sh.directions import make_directions
from prt_addon.core.sh.rotation import axis_angle_matrix
from prt_addon.core.trace import raytrace
from prt_addon.core.transfer import quadrature as transfer

ORDER = 4
Y00 = 1.0 / np.sqrt(4.0 * np.pi)


def cup_coeffs(order, alpha):
    """Shadowed transfer at the bottom of the cup, normal +Z.

    Seen from the bottom point B of a sphere of radius R, every ray into the sphere meets the
    sphere again; it leaves the cup only through the rim disk (radius R, height R above B), i.e.
    inside the cone of half angle alpha = atan(R / R) = 45 degrees about +Z. So
    T(w) = max(0, cos theta) / pi * [theta < alpha], a zonal function with
    z_l = 2 pi integral_{cos alpha}^1 (x / pi) Q_l^0(x) dx. In closed form for l = 0, 1:
    t_0 = sin^2(alpha) / sqrt(4 pi) (the visible cosine-weighted fraction is sin^2 alpha = 1/2)
    and t_(1,0) = 2 sqrt(3 / (4 pi)) (1 - cos^3 alpha) / 3.
    """
    zonal = _zonal_integral(order, np.cos(alpha), 1.0, 1) / np.pi
    return sh.zonal_to_coeffs(zonal, (0.0, 0.0, 1.0))


def wall_visible_fraction(d, h):
    """Cosine-weighted visible fraction at a horizontal point at distance d from a wall of height h.

    The wall is infinitely wide, so the view factor reduces to 2-D (Hottel's crossed strings):
    F = (sin b2 - sin b1) / 2 with b the angles from the normal to the wall's bottom (90 deg)
    and top (atan(d / h)): F = (1 - d / sqrt(d^2 + h^2)) / 2, and the visible fraction is 1 - F.
    """
    return 1.0 - 0.5 * (1.0 - d / np.hypot(d, h))


def test_plane_vertex_shadowed_equals_unshadowed_equals_clamped_cosine():
    normal = np.array([0.3, -0.2, 0.9])
    normal /= np.linalg.norm(normal)
    dirs = make_directions("FIBONACCI", 4096, 1)
    point = np.array([[0.5, 0.1, 2.0]])
    plane = PlaneOccluder(point[0], normal)
    shadowed = transfer.compute_transfer(point, normal[None], dirs, ORDER, plane, offset=1e-4)
    unshadowed = transfer.compute_transfer(point, normal[None], dirs, ORDER, None)
    above = int(np.count_nonzero(dirs.directions @ normal > 0))
    assert shadowed.stats.rays_traced == above
    assert shadowed.stats.occluded_rays == 0
    np.testing.assert_array_equal(shadowed.coeffs, unshadowed.coeffs)
    expected = analytic.clamped_cosine_coeffs(ORDER, normal)
    np.testing.assert_allclose(shadowed.coeffs[0], expected, atol=2e-5)
    # The error estimate is an upper bound here (smooth integrand, Fibonacci set).
    assert np.linalg.norm(shadowed.coeffs[0] - expected) <= shadowed.error[0]


def test_wall_matches_closed_form_visible_fraction():
    d, h = 1.0, 2.0
    dirs = make_directions("FIBONACCI", 8192, 2)
    up = np.array([[0.0, 0.0, 1.0]])
    res = transfer.compute_transfer(np.zeros((1, 3)), up, dirs, ORDER, WallOccluder(d, h), offset=1e-6)
    expected_t0 = Y00 * wall_visible_fraction(d, h)
    assert res.coeffs[0, 0] == pytest.approx(expected_t0, abs=5e-4)
    # Very tall wall: exactly half of the cosine-weighted hemisphere is blocked.
    tall = transfer.compute_transfer(np.zeros((1, 3)), up, dirs, ORDER, WallOccluder(d, 1e9), offset=1e-6)
    assert tall.coeffs[0, 0] == pytest.approx(0.5 * Y00, abs=5e-4)
    # And by symmetry y_(1,-1) (odd in y) vanishes while y_(1,1) (x) is negative (wall at +x).
    assert abs(tall.coeffs[0, 1]) < 1e-3
    assert tall.coeffs[0, 3] < -0.1


def test_cup_matches_closed_form_coefficients():
    alpha = np.pi / 4
    expected = cup_coeffs(ORDER, alpha)
    assert expected[0] == pytest.approx(np.sin(alpha) ** 2 * Y00, rel=1e-12)
    assert expected[2] == pytest.approx(2 * np.sqrt(3 / (4 * np.pi)) * (1 - np.cos(alpha) ** 3) / 3, rel=1e-12)
    dirs = make_directions("FIBONACCI", 8192, 3)
    res = transfer.compute_transfer(
        np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), dirs, ORDER, CupOccluder(), offset=1e-7
    )
    np.testing.assert_allclose(res.coeffs[0], expected, atol=1.5e-3)
    assert np.linalg.norm(res.coeffs[0] - expected) < 3 * res.error[0]


@pytest.mark.skipif(not raytrace.EMBREE_AVAILABLE, reason="embreex not installed")
def test_embree_cup_mesh_matches_closed_form():
    # A finely tessellated cup: rings of latitude on the lower hemisphere of the unit sphere.
    rings, segments = 48, 192
    theta = np.linspace(np.pi, np.pi / 2, rings + 1)[1:]  # from near the bottom to the rim
    phi = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    ring_pts = np.stack(
        [
            np.outer(np.sin(theta), np.cos(phi)),
            np.outer(np.sin(theta), np.sin(phi)),
            1.0 + np.outer(np.cos(theta), np.ones_like(phi)),
        ],
        axis=-1,
    ).reshape(-1, 3)
    verts = np.vstack([[0.0, 0.0, 0.0], ring_pts])
    tris = [(0, 1 + (s + 1) % segments, 1 + s) for s in range(segments)]
    for r in range(rings - 1):
        a, b = 1 + r * segments, 1 + (r + 1) * segments
        for s in range(segments):
            s1 = (s + 1) % segments
            tris += [(a + s, a + s1, b + s1), (a + s, b + s1, b + s)]
    occ = raytrace.EmbreeOccluder(verts, np.array(tris))
    dirs = make_directions("FIBONACCI", 8192, 4)
    res = transfer.compute_transfer(np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), dirs, ORDER, occ, offset=1e-4)
    # The polygonal rim is slightly inside the circle: allow for the tessellation.
    np.testing.assert_allclose(res.coeffs[0], cup_coeffs(ORDER, np.pi / 4), atol=3e-3)


@pytest.mark.parametrize(
    ("kind", "lo", "hi"), [("UNIFORM", 0.7, 1.4), ("STRATIFIED", 0.7, 1.5), ("FIBONACCI", 0.5, 2.0)]
)
def test_error_estimate_tracks_true_error(kind, lo, hi):
    """RMS of |t_A - t_B| / 2 over 32 independent direction sets against the RMS true error, on
    the cup (shadowed): unbiased for i.i.d. and stratified sets, calibrated for Fibonacci (core.transfer.quadrature.error_calibration)."""
    expected = cup_coeffs(ORDER, np.pi / 4)
    true, est = [], []
    for seed in range(32):
        dirs = make_directions(kind, 1024, 100 + seed)
        res = transfer.compute_transfer(
            np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), dirs, ORDER, CupOccluder(), offset=1e-7
        )
        true.append(np.linalg.norm(res.coeffs[0] - expected))
        est.append(res.error[0])
    ratio = np.sqrt(np.mean(np.square(est)) / np.mean(np.square(true)))
    assert lo <= ratio <= hi, ratio


def _clamped_cosine_rows(normals, order):
    bands = sh.band_of_index(order)
    scale = np.sqrt(4.0 * np.pi / (2.0 * bands + 1.0)) * analytic.clamped_cosine_zonal(order)[bands]
    return sh.sh_basis(normals, order) * scale[None, :]


@pytest.mark.parametrize("seed", [0, 11])
def test_uniform_estimate_uses_eight_batch_means(seed, monkeypatch):
    """Uniform sets whose two halves happen to agree (seeds 0 and 11 at 256 directions, order 2:
    the half-set estimate is 0.29x and 0.41x the true RMS error against the analytic clamped
    cosine over 2000 normals); the 8-group batch-means estimate stays within a factor of 2. The
    K = 2 branch is the half-set formula |t_A - t_B| / 2, computed here independently."""
    rng = np.random.default_rng(5)
    normals = rng.normal(size=(2000, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    dirs = make_directions("UNIFORM", 256, seed)
    truth = _clamped_cosine_rows(normals, 2)

    def ratio(result):
        true = np.sqrt(np.mean(np.sum((result.coeffs - truth) ** 2, axis=1)))
        return result.error_rms() / true

    assert transfer.error_groups("UNIFORM") == 8
    eight = transfer.compute_transfer(np.zeros_like(normals), normals, dirs, 2)
    assert 0.5 <= ratio(eight) <= 2.0, ratio(eight)

    monkeypatch.setattr(transfer, "error_groups", lambda kind: 2)
    two = transfer.compute_transfer(np.zeros_like(normals), normals, dirs, 2)
    np.testing.assert_allclose(two.coeffs, eight.coeffs, rtol=1e-6, atol=1e-7)  # only the estimate changes
    y = sh.sh_basis(dirs.directions, 2)
    w = np.maximum(normals @ dirs.directions.T, 0.0) / np.pi
    t_a = 4.0 * np.pi * (w[:, 0::2] @ y[0::2]) / len(y[0::2])
    t_b = 4.0 * np.pi * (w[:, 1::2] @ y[1::2]) / len(y[1::2])
    np.testing.assert_allclose(two.error, np.linalg.norm(t_a - t_b, axis=1) / 2, rtol=1e-5, atol=1e-9)
    assert ratio(two) < 0.5  # what the halves alone would have reported


def test_error_relative_is_rms_error_over_rms_transfer_norm():
    rng = np.random.default_rng(5)
    coeffs = rng.normal(size=(3000, 16)).astype(np.float32)
    error = rng.random(3000).astype(np.float32)
    result = transfer.TransferResult(coeffs, error)
    c64 = coeffs.astype(np.float64)
    expected = np.sqrt(np.mean(error.astype(np.float64) ** 2)) / np.sqrt(np.mean((c64**2).sum(axis=1)))
    assert result.error_relative() == pytest.approx(expected, rel=1e-12)
    assert result.square_norm_sum() == pytest.approx((c64**2).sum(), rel=1e-12)
    assert transfer.TransferResult(coeffs[:0], error[:0]).error_relative() == 0.0


def test_zero_normal_gives_zero_transfer():
    dirs = make_directions("FIBONACCI", 64, 0)
    res = transfer.compute_transfer(np.zeros((1, 3)), np.zeros((1, 3)), dirs, 3)
    assert not res.coeffs.any()


def test_local_frame_rotation_and_mirror():
    order = 4
    normal = np.array([0.2, 0.5, -0.8])
    normal /= np.linalg.norm(normal)
    world = analytic.clamped_cosine_coeffs(order, normal)[None]
    rot = axis_angle_matrix((1, 2, 3), 0.7)
    linear = rot @ np.diag([2.0, 2.0, 2.0])
    local = frames.to_local_frame(world, linear)
    np.testing.assert_allclose(local[0], analytic.clamped_cosine_coeffs(order, rot.T @ normal), atol=1e-12)
    mirror = rot @ np.diag([-1.0, 1.0, 1.0])  # Q = mirror, local direction u maps to world Q u
    local = frames.to_local_frame(world, mirror * 3.0)
    np.testing.assert_allclose(local[0], analytic.clamped_cosine_coeffs(order, mirror.T @ normal), atol=1e-12)


def test_local_frame_of_many_rows_in_float32():
    """2,500 rows (blocks of 1024 and a partial one), float32 in and out: each row is the clamped
    cosine about its own rotated normal, as for a single row."""
    order = 5
    normals = random_directions(2500, seed=4)
    world = np.array([analytic.clamped_cosine_coeffs(order, n) for n in normals], np.float32)
    rot = axis_angle_matrix((0.3, -1, 2), 1.1)
    local = frames.to_local_frame(world, rot * 0.5)
    assert local.dtype == np.float32
    assert local.shape == world.shape
    expected = np.array([analytic.clamped_cosine_coeffs(order, rot.T @ n) for n in normals])
    np.testing.assert_allclose(local, expected, atol=1e-6)
