"""The SH basis against exact quadrature, the addition theorem, scipy and closed forms."""

import numpy as np
import pytest
from helpers.sampling import random_directions
from scipy.special import eval_legendre, sph_harm_y

from prt_addon.core.sh import analytic, basis as sh


def gauss_product_grid(order):
    """Quadrature exact for polynomials of degree < 2*order on the sphere.

    Gauss-Legendre in cos(theta) with `order` nodes times 2*order uniform phi nodes integrates
    every product y_i y_j with l_i, l_j < order exactly (degree <= 2 order - 2 in z, |m| < 2 order).
    """
    z, wz = np.polynomial.legendre.leggauss(order)
    nphi = 2 * order
    phi = 2.0 * np.pi * np.arange(nphi) / nphi
    zz, pp = np.meshgrid(z, phi, indexing="ij")
    s = np.sqrt(1.0 - zz**2)
    dirs = np.stack([s * np.cos(pp), s * np.sin(pp), zz], axis=-1).reshape(-1, 3)
    weights = (wz[:, None] * np.full(nphi, 2.0 * np.pi / nphi)[None, :]).ravel()
    return dirs, weights


@pytest.mark.parametrize("order", [4, 16, 64])
def test_orthonormal_by_exact_quadrature(order):
    dirs, weights = gauss_product_grid(order)
    basis = sh.sh_basis(dirs, order)
    gram = basis.T @ (basis * weights[:, None])
    assert np.abs(gram - np.eye(order * order)).max() < 1e-12


def test_basis_finite_and_orthonormal_to_band_100():
    order = 101
    dirs, weights = gauss_product_grid(order)
    basis = sh.sh_basis(dirs, order)
    assert np.isfinite(basis).all()
    # Every one of the 10201 functions has unit norm ...
    norms = np.einsum("ij,ij,i->j", basis, basis, weights)
    assert np.abs(norms - 1.0).max() < 1e-11
    # ... and bands 0, 1, 50, 99 and 100 are mutually orthonormal (the full Gram matrix costs 2e12
    # flops; these bands include the highest, where a recurrence would lose accuracy first).
    bands = sh.band_of_index(order)
    picked = basis[:, np.isin(bands, [0, 1, 50, 99, 100])]
    gram = picked.T @ (picked * weights[:, None])
    assert np.abs(gram - np.eye(gram.shape[0])).max() < 1e-11


def addition_theorem_check(a, b, order):
    """sum_m y_lm(a) y_lm(b) = (2l+1)/(4 pi) P_l(a.b) for every band l."""
    ya, yb = sh.sh_basis(a, order), sh.sh_basis(b, order)
    bands = sh.band_of_index(order)
    cos_ab = np.einsum("ij,ij->i", a, b)
    for l in range(order):
        lhs = (ya[:, bands == l] * yb[:, bands == l]).sum(axis=1)
        rhs = (2 * l + 1) / (4 * np.pi) * eval_legendre(l, np.clip(cos_ab, -1, 1))
        np.testing.assert_allclose(lhs, rhs, atol=1e-12 * (2 * l + 1))


def test_addition_theorem_random_points():
    addition_theorem_check(random_directions(500, 1), random_directions(500, 2), 30)


def test_addition_theorem_at_poles():
    poles = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    others = np.vstack([poles[:2], random_directions(2, 3)])
    addition_theorem_check(poles, others, 40)
    # Same point twice: sum over the band of y^2 = (2l+1)/(4 pi) exactly, even at the poles.
    addition_theorem_check(poles, poles, 40)


def scipy_real_sh(l, m, theta, phi):
    """Real SH without Condon-Shortley phase from scipy's complex Y_l^m (which includes it)."""
    if m == 0:
        return sph_harm_y(l, 0, theta, phi).real
    y = sph_harm_y(l, abs(m), theta, phi)
    part = y.real if m > 0 else y.imag
    return np.sqrt(2.0) * (-1.0) ** m * part


def test_agrees_with_scipy_to_band_40():
    dirs = np.vstack([random_directions(300, 4), [[0, 0, 1.0], [0, 0, -1.0], [1.0, 0, 0]]])
    theta = np.arccos(np.clip(dirs[:, 2], -1, 1))
    phi = np.arctan2(dirs[:, 1], dirs[:, 0])
    basis = sh.sh_basis(dirs, 41)
    for l in range(41):
        for m in range(-l, l + 1):
            ref = scipy_real_sh(l, m, theta, phi)
            assert np.abs(basis[:, sh.sh_index(l, m)] - ref).max() < 1e-10, (l, m)


def test_band_one_is_y_z_x_without_condon_shortley_phase():
    d = np.array([[0.36, -0.48, 0.8]])
    c = np.sqrt(3.0 / (4.0 * np.pi))
    np.testing.assert_allclose(sh.sh_basis(d, 2)[0], [0.5 / np.sqrt(np.pi), c * -0.48, c * 0.8, c * 0.36], atol=1e-15)


def test_exact_at_poles_and_near_them():
    north = sh.sh_basis(np.array([[0.0, 0.0, 1.0]]), 20)[0]
    bands = sh.band_of_index(20)
    m = np.arange(20 * 20) - bands * (bands + 1)
    # At the pole only m = 0 survives, with value sqrt((2l+1)/(4 pi)).
    np.testing.assert_allclose(north[m == 0], np.sqrt((2 * np.arange(20) + 1) / (4 * np.pi)), rtol=1e-14)
    assert np.all(north[m != 0] == 0.0)
    south = sh.sh_basis(np.array([[0.0, 0.0, -1.0]]), 20)[0]
    np.testing.assert_allclose(south[m == 0], (-1.0) ** np.arange(20) * north[m == 0], rtol=1e-14)
    near = sh.sh_basis(np.array([[1e-12, 0.0, 1.0]]), 20)[0]
    np.testing.assert_allclose(near, north, atol=1e-10)


def test_unnormalised_directions_are_normalised_and_bad_ones_refused():
    d = random_directions(10, 5)
    np.testing.assert_allclose(sh.sh_basis(d * 7.5, 6), sh.sh_basis(d, 6), atol=1e-14)
    with pytest.raises(ValueError, match="zero-length or not finite"):
        sh.sh_basis(np.array([[0.0, 0.0, 0.0]]), 3)
    with pytest.raises(ValueError, match="zero-length or not finite"):
        sh.sh_basis(np.array([[np.nan, 0.0, 1.0]]), 3)
    with pytest.raises(ValueError, match="order"):
        sh.sh_basis(d, 0)


def clamped_cosine_closed_form(l):
    """Zonal coefficient of max(0, cos)/pi from integral_0^1 x P_l(x) dx in closed form."""
    if l == 0:
        integral = 0.5
    elif l == 1:
        integral = 1.0 / 3.0
    elif l % 2:
        integral = 0.0
    else:
        from math import factorial

        integral = (-1) ** (l // 2 + 1) * factorial(l - 2) / (2**l * factorial(l // 2 - 1) * factorial(l // 2 + 1))
    return 2.0 * np.pi * np.sqrt((2 * l + 1) / (4 * np.pi)) * integral / np.pi


def test_clamped_cosine_coefficients():
    zonal = analytic.clamped_cosine_zonal(20)
    np.testing.assert_allclose(zonal[:3], [0.2820948, 0.3257350, 0.1576958], atol=5e-8)
    np.testing.assert_allclose(zonal, [clamped_cosine_closed_form(l) for l in range(20)], atol=1e-15)
    assert np.all(np.abs(zonal[3::2]) < 1e-15)
    coeffs = analytic.clamped_cosine_coeffs(3)  # on the Z axis only m = 0 is non-zero
    np.testing.assert_allclose(coeffs[[0, 2, 6]], [0.2820948, 0.3257350, 0.1576958], atol=5e-8)
    assert np.abs(np.delete(coeffs, [0, 2, 6])).max() < 1e-16


def test_clamped_cosine_about_any_normal_reconstructs_the_function():
    order = 40
    normal = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    coeffs = analytic.clamped_cosine_coeffs(order, normal)
    dirs = random_directions(2000, 6)
    approx = sh.evaluate(coeffs, dirs)
    exact = np.maximum(0.0, dirs @ normal) / np.pi
    # Truncation error of a kinked function: its zonal coefficients decay as l^-5/2.
    assert np.abs(approx - exact).max() < 5e-3
    assert np.sqrt(np.mean((approx - exact) ** 2)) < 5e-4


def test_spherical_cap_matches_closed_form_and_solid_angle():
    alpha = np.radians(5.0)
    zonal = analytic.cap_zonal(30, alpha)
    closed = [2 * np.pi * np.sqrt(1 / (4 * np.pi)) * (1 - np.cos(alpha))] + [
        2
        * np.pi
        * np.sqrt((2 * l + 1) / (4 * np.pi))
        * (eval_legendre(l - 1, np.cos(alpha)) - eval_legendre(l + 1, np.cos(alpha)))
        / (2 * l + 1)
        for l in range(1, 30)
    ]
    np.testing.assert_allclose(zonal, closed, rtol=1e-9, atol=1e-15)
    coeffs = analytic.cap_coeffs(8, (1.0, 0.0, 0.0), alpha, radiance=[1e4, 2e4, 3e4])
    # c_0 * y_0 * 4 pi = integral of the function = radiance * solid angle 2 pi (1 - cos alpha).
    np.testing.assert_allclose(
        coeffs[0] * np.sqrt(4 * np.pi), np.array([1e4, 2e4, 3e4]) * 2 * np.pi * (1 - np.cos(alpha)), rtol=1e-13
    )


def test_convolution_with_clamped_cosine_equals_per_normal_transfer():
    """Funk-Hecke: evaluating the convolved lighting at n equals dot(L, clamped cosine about n)."""
    rng = np.random.default_rng(9)
    order = 8
    light = rng.normal(size=(order * order, 3))
    normals = random_directions(20, 10)
    convolved = sh.evaluate(sh.convolve_zonal(light, analytic.clamped_cosine_zonal(order)), normals)
    direct = np.stack([analytic.clamped_cosine_coeffs(order, n) @ light for n in normals])
    np.testing.assert_allclose(convolved, direct, atol=1e-13)


def test_evaluate_in_chunks_matches_one_block(monkeypatch):
    coeffs = np.random.default_rng(1).normal(size=(25, 2))
    dirs = random_directions(1000, 2)
    whole = sh.sh_basis(dirs, 5) @ coeffs
    monkeypatch.setattr(sh, "EVALUATE_CHUNK", 64)
    np.testing.assert_allclose(sh.evaluate(coeffs, dirs), whole, atol=1e-14)
