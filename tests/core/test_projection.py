"""Equirectangular projection: solid angles, exact constants, round trips, pixel policy."""

import numpy as np
import pytest

from prt_addon import api
from prt_addon.core.sh import basis as sh, projection


def test_pixel_solid_angles_sum_to_4pi():
    for height, width in [(512, 1024), (256, 512), (1, 1), (1, 2), (3, 7), (4096, 8192)]:
        total = projection.pixel_solid_angles(height, width).sum() * width
        assert abs(total - 4 * np.pi) < 1e-12


def test_blender_convention_pixel_directions():
    """+X is the image centre, row 0 the nadir, u increases towards -Y."""
    height, width = 64, 128
    d = projection.pixel_directions(height, width)
    u = -np.arctan2(d[..., 1], d[..., 0]) / (2 * np.pi) + 0.5
    v = np.arctan2(d[..., 2], np.hypot(d[..., 0], d[..., 1])) / np.pi + 0.5
    np.testing.assert_allclose(u, ((np.arange(width) + 0.5) / width)[None, :].repeat(height, 0), atol=1e-12)
    np.testing.assert_allclose(v, ((np.arange(height) + 0.5) / height)[:, None].repeat(width, 1), atol=1e-12)


@pytest.mark.parametrize("shape", [(256, 512, 4), (512, 1024, 3), (1, 1, 4), (1, 2, 4), (5, 3, 1), (7, 9, 2)])
def test_uniform_white_environment_is_exact(shape):
    coeffs = api.project_equirect(np.ones(shape, np.float32), 8)
    np.testing.assert_allclose(coeffs[0], np.sqrt(4 * np.pi), rtol=1e-12)
    assert np.abs(coeffs[1:]).max() < 1e-12


def test_separable_sum_equals_brute_force_pixel_integrals():
    """Independent evaluation: integrate every basis function over every pixel by dense sampling."""
    rng = np.random.default_rng(7)
    height, width, order = 6, 10, 5
    image = rng.random((height, width, 3))
    sub = 24  # sub-samples per pixel side: midpoint rule in (elevation, phi) with cos(e) Jacobian
    e_edges = (np.arange(height + 1) / height - 0.5) * np.pi
    phi_edges = np.pi - 2 * np.pi * np.arange(width + 1) / width
    expected = np.zeros((order * order, 3))
    for j in range(height):
        e = e_edges[j] + (np.arange(sub) + 0.5) / sub * (e_edges[j + 1] - e_edges[j])
        for k in range(width):
            phi = phi_edges[k] + (np.arange(sub) + 0.5) / sub * (phi_edges[k + 1] - phi_edges[k])
            ee, pp = np.meshgrid(e, phi, indexing="ij")
            dirs = np.stack([np.cos(ee) * np.cos(pp), np.cos(ee) * np.sin(pp), np.sin(ee)], -1).reshape(-1, 3)
            area = np.cos(ee).ravel() * (np.pi / height / sub) * (2 * np.pi / width / sub)
            expected += np.outer(sh.sh_basis(dirs, order).T @ area, image[j, k])
    got = api.project_equirect(image, order)
    np.testing.assert_allclose(got, expected, atol=2e-4 * np.abs(expected).max())


def test_synthesised_image_projects_back():
    """An image sampled at 512x256 from known coefficients projects back to them.

    The image holds point samples while the projection integrates each pixel as a constant, so
    band l is attenuated by averaging over a pixel of angular size d = pi/256: to second order
    1 - l(l+1) d^2 / 24 (the mean of the Laplacian over a d x d square, eigenvalue -l(l+1)).
    Order 8 (l <= 7) gives a relative error below 56 d^2/24 = 3.5e-4; we allow 5e-4 of the
    largest coefficient, and the error must also be > 0 at l = 7 in the predicted direction.
    """
    rng = np.random.default_rng(11)
    order = 8
    coeffs = rng.normal(size=(order * order, 3))
    coeffs[0] += 40.0  # keep the image positive: negative pixels would be clamped
    image = projection.synthesize_equirect(coeffs, 256, 512).astype(np.float32)
    got, report = projection.project_equirect(image, order)
    assert report.repaired == 0
    assert np.abs(got - coeffs).max() < 5e-4 * np.abs(coeffs).max()
    bands = sh.band_of_index(order)
    ratio = got[bands == 7] / coeffs[bands == 7]
    assert np.median(ratio) < 1.0


def test_projection_of_image_equals_projection_of_rotated_image_about_z():
    """Turning the image by whole columns is a rotation about Z: the SH rotation must agree."""
    from prt_addon.core.sh import rotation

    rng = np.random.default_rng(3)
    image = rng.random((32, 64, 3))
    shift = 16  # 16 of 64 columns = 90 degrees; columns move towards -phi as k increases
    rolled = np.roll(image, shift, axis=1)
    c0 = api.project_equirect(image, 6)
    c1 = api.project_equirect(rolled, 6)
    angle = -2 * np.pi * shift / 64
    np.testing.assert_allclose(rotation.z_rotation_matrix(angle, 6) @ c0, c1, atol=1e-12)


def test_nan_inf_negative_policy():
    image = np.ones((16, 32, 4), np.float32)
    image[3, 4, 0] = np.nan
    image[5, 6, 1] = np.inf
    image[7, 8, 2] = -np.inf
    image[9, 10, 0] = -5.0
    image[:, :, 3] = np.nan  # alpha is ignored
    coeffs, report = projection.project_equirect(image, 4)
    assert (report.nan, report.inf, report.negative) == (1, 2, 1)
    assert np.isfinite(coeffs).all()
    assert "1 NaN and 2 infinite values set to 0, 1 negative values clamped to 0" == report.summary()
    # The repaired pixels count as 0: compare with an image where they are 0 to begin with.
    clean = np.ones((16, 32, 3))
    clean[3, 4, 0] = clean[5, 6, 1] = clean[7, 8, 2] = clean[9, 10, 0] = 0.0
    np.testing.assert_allclose(coeffs, projection.project_equirect(clean, 4)[0], atol=1e-14)


def test_grey_and_bad_shapes():
    grey = np.full((8, 16, 1), 2.0)
    np.testing.assert_allclose(api.project_equirect(grey, 2)[0], [2 * np.sqrt(4 * np.pi)] * 3, rtol=1e-12)
    with pytest.raises(ValueError, match="shape"):
        api.project_equirect(np.ones((0, 4, 3)), 2)
    with pytest.raises(ValueError, match="order"):
        api.project_equirect(np.ones((4, 8, 3)), 0)


def test_sun_disk_projection_matches_analytic_cap():
    """A bright sun painted into a 1024x512 image projects to the analytic cap to pixel accuracy."""
    from prt_addon.core.sh import analytic

    height, width, order = 512, 1024, 8
    alpha = np.radians(5.0)
    axis = np.array([0.3, 0.5, 0.6]) / np.linalg.norm([0.3, 0.5, 0.6])
    dirs = projection.pixel_directions(height, width)
    image = np.where((dirs @ axis) >= np.cos(alpha), 1e4, 0.0)[..., None].repeat(3, axis=2)
    got = api.project_equirect(image, order)
    expected = analytic.cap_coeffs(order, axis, alpha, radiance=[1e4] * 3)
    # Pixels on the disk edge are all-or-nothing: relative error ~ (edge pixels / disk pixels).
    assert np.abs(got - expected).max() < 0.03 * np.abs(expected).max()
