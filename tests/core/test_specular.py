"""The split-sum BRDF table, its energy compensation and the specular occlusion (core.specular) against
brute-force integrals, closed forms and the white furnace."""

import numpy as np
import pytest
from scipy import integrate

from prt_addon.core.sh import analytic, basis as sh
from prt_addon.core.specular import brdf, occlusion


def _fibonacci(n):
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = np.pi * (1.0 + 5.0**0.5) * i
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _albedo_by_quadrature(mu, alpha, f0=1.0, factor=1.0):
    """int f_ss mu_l dl over the hemisphere of l, in spherical coordinates (scipy)."""
    v = np.array([np.sqrt(1.0 - mu * mu), 0.0, mu])

    def f(phi, theta):
        l = np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])
        h = (v + l) / np.linalg.norm(v + l)
        fresnel = f0 + (1.0 - f0) * (1.0 - v @ h) ** 5
        return brdf.ggx_d(h[2], alpha) * brdf.g2(mu, l[2], alpha) * fresnel / (4.0 * mu) * np.sin(theta) * factor

    return integrate.dblquad(f, 0.0, np.pi / 2, 0.0, 2.0 * np.pi, epsabs=1e-7)[0]


@pytest.mark.parametrize("roughness", [0.3, 0.6, 1.0])
@pytest.mark.parametrize("mu", [0.1, 0.5, 0.95])
def test_split_sum_matches_a_direct_integral(roughness, mu):
    alpha = float(brdf.alpha_of(roughness))
    a, b = brdf.split_sum(mu, alpha)
    for f0 in (0.04, 1.0):
        assert f0 * a + b == pytest.approx(_albedo_by_quadrature(mu, alpha, f0), abs=3e-3)


def test_split_sum_at_a_mirror_is_schlick():
    """alpha -> 0: G -> 1 and h = n, so F0 A + B -> Schlick's F at the view angle."""
    mu = np.array([0.2, 0.5, 0.9])
    a, b = brdf.split_sum(mu, 1e-3)
    schlick = lambda f0: f0 + (1.0 - f0) * (1.0 - mu) ** 5
    assert np.allclose(a + b, 1.0, atol=2e-3)
    assert np.allclose(0.04 * a + b, schlick(0.04), atol=2e-3)


def test_table_layout():
    table = brdf.brdf_table(8, samples=512)
    c = brdf.table_coordinates(8)
    a, b = brdf.split_sum(c[2], brdf.alpha_of(c[5]), 512)
    assert table.shape == (8, 8, 2)
    assert table[5, 2] == pytest.approx([a, b])


def test_white_furnace_metal_and_dielectric():
    """A white conductor and a white Principled dielectric reflect 1 at roughness 0.1 to 1."""
    table = brdf.brdf_table(16, samples=1024)
    a, b = table[..., 0], table[..., 1]
    rough = brdf.table_coordinates(16)[:, None] * np.ones((1, 16))
    keep = rough >= 0.1
    metal = brdf.specular_albedo(1.0, a, b)
    assert np.allclose(metal[keep], 1.0, atol=1e-9)
    for ior in (1.33, 1.5, 2.4):
        spec, diffuse = brdf.principled_weights(1.0, 0.0, brdf.dielectric_f0(ior), a, b)
        assert np.allclose((spec + diffuse * 1.0)[keep], 1.0, atol=1e-9)
        assert np.all(spec[keep] > 0.0) and np.all(diffuse[keep] > 0.0)
    # Single scattering alone loses energy (E_ss < 1 for rough lobes): the compensation matters.
    assert (a + b)[rough > 0.6].min() < 0.5


@pytest.mark.parametrize("roughness", [0.3, 0.7, 1.0])
def test_analytic_light_compensation_is_a_white_furnace(roughness):
    """A white conductor's single lobe times Turquin's factor integrates to 1 (scipy)."""
    alpha = float(brdf.alpha_of(roughness))
    for mu in (0.3, 0.8):
        a, b = brdf.split_sum(mu, alpha)
        factor = float(brdf.energy_compensation(1.0, a, b))
        assert _albedo_by_quadrature(mu, alpha, 1.0, factor) == pytest.approx(1.0, abs=3e-3)


def test_dielectric_f0():
    assert brdf.dielectric_f0(1.5) == pytest.approx(0.04)
    assert brdf.dielectric_f0(1.5, 1.0) == pytest.approx(0.08)
    assert brdf.dielectric_f0(1.0) == 0.0
    assert brdf.dielectric_f0(1.5, 0.0) == 0.0


def test_cap_intersection_matches_quadrature():
    d = _fibonacci(2_000_000)
    for a, b, g in [
        (0.5, 0.7, 0.6),
        (1.2, 0.3, 1.0),
        (np.pi / 2, 0.4, 1.5),
        (1.0, 1.0, 0.1),
        (2.0, 0.5, 2.2),
        (0.3, 0.2, 1.0),
        (1.0, 0.2, 0.3),
    ]:
        ax, bx = np.array([0.0, 0.0, 1.0]), np.array([np.sin(g), 0.0, np.cos(g)])
        count = np.mean((d @ ax > np.cos(a)) & (d @ bx > np.cos(b))) * 4.0 * np.pi
        assert occlusion.cap_intersection(np.cos(a), np.cos(b), np.cos(g)) == pytest.approx(count, abs=2e-4)


def _cone_transfer(d, normal, cos_hole, order):
    """Transfer (visibility x max(n.l, 0) / pi) of a point that sees only a cone about its normal."""
    visible = (d @ normal > cos_hole) * np.maximum(d @ normal, 0.0) / np.pi
    return sh.sh_basis(d, order).T @ visible * (4.0 * np.pi / len(d))


def test_visibility_cone_of_a_hole_is_exact():
    """A point at the bottom of a cone of half-angle theta: AO = sin^2 theta, bent normal = n."""
    d = _fibonacci(400_000)
    normal = np.array([0.6, 0.0, 0.8])
    for theta in (0.4, 0.9, 1.3):
        ao, bent, cos_v = occlusion.visibility_cone(_cone_transfer(d, normal, np.cos(theta), 2))
        assert ao == pytest.approx(np.sin(theta) ** 2, abs=5e-4)
        assert cos_v == pytest.approx(np.cos(theta), abs=1e-3)
        assert np.allclose(bent, normal, atol=5e-4)


def test_open_surface_is_not_occluded():
    """The open transfer (the clamped cosine's SH) occludes nothing, at any lobe tilt and width."""
    normal = np.array([0.0, 0.0, 1.0])
    t_open = analytic.clamped_cosine_coeffs(6, normal)
    for tilt in (0.0, 0.7, 1.4):
        r = np.array([np.sin(tilt), 0.0, np.cos(tilt)])
        for roughness in (0.1, 0.5, 1.0):
            alpha = float(brdf.alpha_of(roughness))
            assert occlusion.specular_occlusion(t_open[:4], normal, r, alpha) == pytest.approx(1.0)
            y = sh.sh_basis(r[None], 6)[0]
            assert occlusion.transfer_occlusion(t_open, t_open, y, occlusion.lobe_bands(alpha, 6)) == pytest.approx(1.0)


def _lobe_truth(d, normal, r, alpha, visible):
    lobe = brdf.ggx_d(np.sqrt((1.0 + d @ r) / 2.0), alpha) * np.maximum(d @ r, 0.0) * np.maximum(d @ normal, 0.0)
    return (lobe * visible).sum() / lobe.sum()


@pytest.mark.parametrize("theta", [0.5, 0.9, 1.2])
def test_occlusion_of_a_hole_against_the_lobe_integral(theta):
    """A point seeing a cone of half-angle theta about its normal, the lobe tilted by 0 to 1 rad:
    the cones (Jimenez) within 0.2 of the brute-force lobe integral for sharp lobes (r <= 0.3),
    the full-transfer estimate (order 8) within 0.02 for rough ones (r >= 0.6)."""
    d = _fibonacci(200_000)
    normal = np.array([0.0, 0.0, 1.0])
    t = _cone_transfer(d, normal, np.cos(theta), 8)
    t_open = analytic.clamped_cosine_coeffs(8, normal)
    visible = (d @ normal > np.cos(theta)).astype(float)
    for tilt in (0.0, 0.5, 1.0):
        r = np.array([np.sin(tilt), 0.0, np.cos(tilt)])
        for roughness in (0.1, 0.3, 0.6, 1.0):
            alpha = float(brdf.alpha_of(roughness))
            truth = _lobe_truth(d, normal, r, alpha, visible)
            if roughness <= 0.3:
                assert occlusion.specular_occlusion(t[:4], normal, r, alpha) == pytest.approx(truth, abs=0.2)
            else:
                y = sh.sh_basis(r[None], 8)[0]
                est = occlusion.transfer_occlusion(t, t_open, y, occlusion.lobe_bands(alpha, 8))
                assert est == pytest.approx(truth, abs=0.02)
