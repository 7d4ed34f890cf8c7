"""SH rotation: orthogonality, composition, closed form about Z, and f(R^-1 w) at order 12."""

import numpy as np
import pytest
from helpers.sampling import random_directions

from prt_addon import api
from prt_addon.core.sh import basis as sh, directions, rotation

ORDER = 12


def rotations(count, seed):
    rng = np.random.default_rng(seed)
    return [directions.random_rotation(rng) for _ in range(count)]


def test_rotation_matrices_are_orthogonal_and_block_diagonal():
    for r in rotations(3, 1):
        m = api.rotation_matrix(r, ORDER)
        assert np.abs(m @ m.T - np.eye(ORDER * ORDER)).max() < 1e-13
        bands = sh.band_of_index(ORDER)
        assert np.all(m[bands[:, None] != bands[None, :]] == 0.0)


def test_composition():
    a, b = rotations(2, 2)
    lhs = api.rotation_matrix(a, ORDER) @ api.rotation_matrix(b, ORDER)
    assert np.abs(lhs - api.rotation_matrix(a @ b, ORDER)).max() < 1e-13


@pytest.mark.parametrize("angle", [0.0, np.pi / 2, np.radians(37.0), np.pi, -2.5])
def test_matches_closed_form_about_z(angle):
    general = api.rotation_matrix(rotation.axis_angle_matrix((0, 0, 1), angle), ORDER)
    assert np.abs(general - rotation.z_rotation_matrix(angle, ORDER)).max() < 1e-13
    coeffs = np.random.default_rng(0).normal(size=(ORDER * ORDER, 3))
    np.testing.assert_allclose(rotation.rotate_z(coeffs, angle), general @ coeffs, atol=1e-13)
    np.testing.assert_allclose(rotation.rotate_z(coeffs[:, 0], angle), general @ coeffs[:, 0], atol=1e-13)


def test_rotated_coefficients_evaluate_to_the_function_at_inverse_rotated_directions():
    rng = np.random.default_rng(3)
    coeffs = rng.normal(size=(ORDER * ORDER, 3))
    w = random_directions(400, 4)
    for r in rotations(3, 5) + [rotation.euler_xyz_matrix((0.3, -1.2, 2.0))]:
        rotated = api.rotation_matrix(r, ORDER) @ coeffs
        # rows of w @ r are R^T w = R^-1 w
        np.testing.assert_allclose(sh.evaluate(rotated, w), sh.evaluate(coeffs, w @ r), atol=1e-12)
        np.testing.assert_allclose(rotation.rotate(coeffs, r), rotated, atol=1e-14)


def test_zonal_function_rotated_to_an_axis():
    """Rotating the clamped cosine about +Z onto n gives the clamped cosine about n."""
    from prt_addon.core.sh import analytic

    n = np.array([0.6, 0.0, -0.8])
    # A rotation taking +Z to n: about the Y axis by the angle between them.
    r = rotation.axis_angle_matrix((0, 1, 0), np.arctan2(0.6, -0.8))
    np.testing.assert_allclose(r @ [0, 0, 1], n, atol=1e-15)
    np.testing.assert_allclose(
        rotation.rotate(analytic.clamped_cosine_coeffs(ORDER), r), analytic.clamped_cosine_coeffs(ORDER, n), atol=1e-14
    )


def test_high_order_stays_orthogonal():
    m = rotation.rotation_matrix(rotations(1, 6)[0], 65)
    assert np.abs(m @ m.T - np.eye(65 * 65)).max() < 1e-10


def test_refuses_non_rotations():
    with pytest.raises(ValueError, match="orthogonal"):
        api.rotation_matrix(np.diag([1.0, 1.0, -1.0]), 3)
    with pytest.raises(ValueError, match="orthogonal"):
        api.rotation_matrix(2 * np.eye(3), 3)
    with pytest.raises(ValueError, match="3x3"):
        api.rotation_matrix(np.full((3, 3), np.nan), 3)
