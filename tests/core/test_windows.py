"""Tests of benchmarks/windows (not shipped in the add-on): SH ringing windows and the automatic parameter search.

Expectations are computed independently of the module: closed-form window values typed in by
hand, zonal test functions evaluated through the addition theorem with scipy's Legendre
polynomials, sum_m c_lm y_lm(x) = z_l sqrt((2l+1)/(4 pi)) P_l(axis . x), rather than through
sh_basis, and exact answers for a linear function.
"""

import functools
import math

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.spatial import cKDTree
from scipy.special import eval_legendre

from benchmarks.windows import (
    DEFAULT_TOL,
    apply_window,
    auto_window,
    sphere_grid,
    window_weights,
)
from prt_addon.core.sh import basis as sh

KINDS = ("HANNING", "LANCZOS", "LAPLACIAN")
AXIS = np.array([0.3, -0.5, 0.81]) / np.linalg.norm([0.3, -0.5, 0.81])  # generic direction
ALPHA = math.radians(5.0)  # the sun: a cap of 5 degrees ...
SUN, BACKGROUND = 1e4, 1.0  # ... of radiance 1e4 on a background of 1


# ---------------------------------------------------------------------------------------------
# Independent helpers
# ---------------------------------------------------------------------------------------------


def cap_zonal(order, alpha, inside, outside):
    """Zonal coefficients of `inside` on the cap of radius alpha about +Z, `outside` elsewhere.

    z_l = 2 pi sqrt((2l+1)/(4 pi)) int_{cos alpha}^1 P_l(x) dx (Gauss-Legendre, exact for
    these polynomial degrees), plus the constant `outside` in band 0.
    """
    nodes, wts = np.polynomial.legendre.leggauss(64)
    ca = math.cos(alpha)
    x = 0.5 * (1.0 - ca) * nodes + 0.5 * (1.0 + ca)
    w = 0.5 * (1.0 - ca) * wts
    z = np.array(
        [2.0 * np.pi * math.sqrt((2 * l + 1) / (4 * np.pi)) * np.sum(w * eval_legendre(l, x)) for l in range(order)]
    )
    z *= inside - outside
    z[0] += outside * math.sqrt(4.0 * np.pi)
    return z


def zonal_matrix(order, axis, dirs):
    """(N, order): sqrt((2l+1)/(4 pi)) P_l(axis . x), so f(x) = matrix @ (w_l z_l)."""
    t = np.clip(dirs @ axis, -1.0, 1.0)
    return np.stack([math.sqrt((2 * l + 1) / (4 * np.pi)) * eval_legendre(l, t) for l in range(order)], axis=1)


def random_directions(count, seed):
    d = np.random.default_rng(seed).normal(size=(count, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


@functools.lru_cache(maxsize=None)
def sun_case(order):
    """Coefficients of the sun, its zonal coefficients, and evaluation matrices."""
    z = cap_zonal(order, ALPHA, SUN, BACKGROUND)
    coeffs = sh.zonal_to_coeffs(z, AXIS)
    mean = coeffs[0] / math.sqrt(4.0 * np.pi)
    on_grid = zonal_matrix(order, AXIS, sphere_grid(order))
    on_random = zonal_matrix(order, AXIS, random_directions(200_000, seed=1234))
    return z, coeffs, mean, on_grid, on_random


# ---------------------------------------------------------------------------------------------
# Window weights
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kind", "param"),
    [
        ("NONE", None),
        ("HANNING", None),
        ("HANNING", 0.5),
        ("HANNING", 2.3),
        ("LANCZOS", None),
        ("LANCZOS", 0.7),
        ("LANCZOS", 9.0),
        ("LAPLACIAN", 0.0),
        ("LAPLACIAN", 1e3),
    ],
)
@pytest.mark.parametrize("order", [1, 2, 5, 16])
def test_band_zero_weight_is_one(kind, param, order):
    w = window_weights(kind, order, param)
    assert w.shape == (order,)
    assert w.dtype == np.float64
    assert w[0] == 1.0


def test_none_is_identity():
    assert np.array_equal(window_weights("NONE", 7), np.ones(7))
    assert np.array_equal(window_weights("none", 3, 1.5), np.ones(3))  # param ignored
    c = np.random.default_rng(0).normal(size=(49, 3))
    assert np.array_equal(apply_window(c, window_weights("NONE", 7)), c)


def test_hanning_closed_form():
    r2 = math.sqrt(2.0)
    # width = order = 4 (the default): cos(pi/4), cos(pi/2), cos(3 pi/4)
    expected = [1.0, (1 + r2 / 2) / 2, 0.5, (1 - r2 / 2) / 2]
    assert np.allclose(window_weights("HANNING", 4), expected, rtol=0, atol=1e-15)
    assert np.allclose(window_weights("HANNING", 4, 4.0), expected, rtol=0, atol=1e-15)
    # width 2.5: cos(0.4 pi) = (sqrt5 - 1)/4, cos(0.8 pi) = -(sqrt5 + 1)/4, l = 3 >= width -> 0
    s5 = math.sqrt(5.0)
    expected = [1.0, (1 + (s5 - 1) / 4) / 2, (1 - (s5 + 1) / 4) / 2, 0.0, 0.0]
    assert np.allclose(window_weights("HANNING", 5, 2.5), expected, rtol=0, atol=1e-15)
    # order 3, default: 1, 3/4, 1/4 (the last band is still > 0)
    assert np.allclose(window_weights("HANNING", 3), [1.0, 0.75, 0.25], rtol=0, atol=1e-15)
    # width <= 1 keeps band 0 only; width = inf is no window
    assert np.array_equal(window_weights("HANNING", 4, 1.0), [1.0, 0.0, 0.0, 0.0])
    assert np.array_equal(window_weights("HANNING", 4, math.inf), np.ones(4))


def test_lanczos_closed_form():
    r2 = math.sqrt(2.0)
    # width 4: sin(pi/4)/(pi/4), sin(pi/2)/(pi/2), sin(3pi/4)/(3pi/4)
    expected = [1.0, (r2 / 2) / (np.pi / 4), 2.0 / np.pi, (r2 / 2) / (3 * np.pi / 4)]
    assert np.allclose(window_weights("LANCZOS", 4), expected, rtol=0, atol=1e-15)
    assert np.allclose(expected[1:], [0.9003163161571061, 0.6366197723675814, 0.3001054387190354])
    # width 3 at order 5: l = 3, 4 are cut; sin(pi/3)/(pi/3), sin(2 pi/3)/(2 pi/3)
    r3 = math.sqrt(3.0)
    expected = [1.0, (r3 / 2) / (np.pi / 3), (r3 / 2) / (2 * np.pi / 3), 0.0, 0.0]
    assert np.allclose(window_weights("LANCZOS", 5, 3.0), expected, rtol=0, atol=1e-15)
    assert np.array_equal(window_weights("LANCZOS", 4, math.inf), np.ones(4))


def test_laplacian_closed_form_and_monotone():
    lam = 0.01
    expected = [1.0, 1 / (1 + lam * 4), 1 / (1 + lam * 36), 1 / (1 + lam * 144)]
    assert np.allclose(window_weights("LAPLACIAN", 4, lam), expected, rtol=1e-15)
    assert np.array_equal(window_weights("LAPLACIAN", 6, 0.0), np.ones(6))
    lams = [1e-6, 1e-4, 1e-2, 1.0, 100.0]
    ws = np.array([window_weights("LAPLACIAN", 16, x) for x in lams])
    assert (np.diff(ws[:, 1:], axis=1) < 0).all()  # strictly decreasing in l >= 1
    assert (np.diff(ws[:, 1:], axis=0) < 0).all()  # strictly decreasing in lambda
    assert ((ws > 0) & (ws <= 1)).all()


# (kind, param, what window_weights says) of test_bad_kind_or_param_raises.
BAD_WINDOWS = [
    ("GAUSS", None, r"window kind must be one of NONE, HANNING, LANCZOS, LAPLACIAN \(got 'GAUSS'\)"),
    (None, None, r"window kind must be one of NONE, HANNING, LANCZOS, LAPLACIAN \(got None\)"),
    ("HANNING", 0.0, r"width must be > 0 \(got 0.0\)"),
    ("HANNING", -1.0, r"width must be > 0 \(got -1.0\)"),
    ("LANCZOS", float("nan"), "width must not be NaN"),
    ("LANCZOS", "wide", r"width must be a real number \(got 'wide'\)"),
    ("LAPLACIAN", None, r"the LAPLACIAN window needs lambda \(>= 0\); there is no data-independent default"),
    ("LAPLACIAN", -0.1, r"lambda must be finite and >= 0 \(got -0.1\)"),
    ("LAPLACIAN", math.inf, r"lambda must be finite and >= 0 \(got inf\)"),
]


@pytest.mark.parametrize(("kind", "param"), [case[:2] for case in BAD_WINDOWS])
def test_bad_kind_or_param_raises(kind, param):
    message = next(m for k, p, m in BAD_WINDOWS if k == kind and p is param)
    with pytest.raises(ValueError, match=message):
        window_weights(kind, 4, param)


# ---------------------------------------------------------------------------------------------
# apply_window
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("shape_tail", [(), (3,)])
def test_apply_window_scales_band_by_band(shape_tail):
    order = 6
    rng = np.random.default_rng(7)
    c = rng.normal(size=(order * order,) + shape_tail)
    w = rng.uniform(0.1, 2.0, size=order)
    out = apply_window(c, w)
    assert out.shape == c.shape
    expected = c.copy()
    for l in range(order):
        for m in range(-l, l + 1):
            expected[l * l + l + m] = c[l * l + l + m] * w[l]
    assert np.array_equal(out, expected)
    assert not np.array_equal(c, expected)  # the input is left untouched (weights != 1)


def test_apply_window_rejects_mismatched_weights():
    with pytest.raises(ValueError, match=r"weights must have shape \(4,\) for order 4, got \(3,\)"):
        apply_window(np.ones(16), np.ones(3))
    with pytest.raises(ValueError, match=r"15 coefficients is not a square number \(order\*\*2\)"):
        apply_window(np.ones(15), np.ones(4))


# ---------------------------------------------------------------------------------------------
# sphere_grid
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("order", [2, 4, 8, 16])
def test_sphere_grid_is_dense_and_has_poles(order):
    g = sphere_grid(order)
    assert np.allclose(np.linalg.norm(g, axis=1), 1.0, atol=1e-15)
    assert (g == [0.0, 0.0, 1.0]).all(axis=1).any()
    assert (g == [0.0, 0.0, -1.0]).all(axis=1).any()
    # covering radius: every direction is within ~pi / (6 n) of a grid point, well below the
    # pi / n half-wavelength of band n-1
    probe = random_directions(50_000, seed=3)
    chord, _ = cKDTree(g).query(probe)
    angle = 2.0 * np.arcsin(np.minimum(chord / 2.0, 1.0))
    h = np.pi / max(math.ceil(6 * order), 16)
    assert angle.max() < 0.8 * h
    assert angle.max() < np.pi / order / 4


# ---------------------------------------------------------------------------------------------
# auto_window: exact answers
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("order", [2, 5])
def test_auto_window_exact_for_linear_function(kind, order):
    # f = c0 y00 + c1 y_{1,1} = 0.564 + 1.466 x (c0 = 2, c1 = 3): min at -X, and the window
    # must bring band 1 down to exactly w* = c0 y00 / (|c1| sqrt(3/(4 pi))) = 2 / (3 sqrt 3).
    c = np.zeros(order * order)
    c[0], c[3] = 2.0, 3.0
    w_star = 2.0 / (3.0 * math.sqrt(3.0))
    if kind == "LAPLACIAN":
        expected = (1.0 / w_star - 1.0) / 4.0
    elif kind == "HANNING":
        expected = np.pi / math.acos(2.0 * w_star - 1.0)
    else:
        expected = 1.0 / brentq(lambda u: np.sinc(u) - w_star, 1e-9, 1.0 - 1e-12)
    r = auto_window(c, kind)
    assert r.param == pytest.approx(expected, rel=1e-4)
    assert r.weights[1] == pytest.approx(w_star, rel=1e-4)
    assert r.weights[1] <= w_star * (1 + 1e-6)  # not weaker than the exact answer (to tol)


# ---------------------------------------------------------------------------------------------
# auto_window: the sun
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("order", [3, 4, 8, 12, 16])
def test_auto_window_removes_sun_ringing(kind, order):
    z, coeffs, mean, on_grid, on_random = sun_case(order)
    floor = -DEFAULT_TOL * mean

    # the unwindowed sun rings negative, by a lot, on the grid
    assert (on_grid @ z).min() < -0.5 * mean

    r = auto_window(coeffs, kind)
    assert r.kind == kind
    assert np.array_equal(r.weights, window_weights(kind, order, r.param))
    assert r.min_value_before < -0.5 * mean
    assert r.min_value_after >= floor
    assert 0.0 < r.param < math.inf

    # windowed: non-negative (to the tolerance) on the grid and on 200k random directions;
    # the random set gets 2x slack for the finite precision of the local refinement
    assert (on_grid @ (r.weights * z)).min() >= floor
    assert (on_random @ (r.weights * z)).min() >= 2.0 * floor

    # and it is the weakest: a slightly weaker window is clearly negative on the grid
    weaker = r.param * 0.9 if kind == "LAPLACIAN" else r.param * 1.05
    assert (on_grid @ (window_weights(kind, order, weaker) * z)).min() < -1e-3 * mean


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("order", [3, 8, 16])
def test_auto_window_is_weakest_by_brute_force(kind, order):
    # a milder light (15 degrees, 100 : 1) keeps several bands. The function is zonal, so its
    # exact minimum is that of a 1-D profile over theta (sampled at 40 000 angles). Scan 300
    # weaker parameters: none may pass. (The minimum is not monotone in the parameter: e.g.
    # LANCZOS at order 8 has a feasible island of widths near 6.44 above infeasible ones.)
    # The sphere grid alone would not do here: between its points a weaker window can still
    # dip below zero, which auto_window's local refinement sees.
    z = cap_zonal(order, math.radians(15.0), 100.0, 1.0)
    coeffs = sh.zonal_to_coeffs(z, AXIS)
    mean = coeffs[0] / math.sqrt(4.0 * np.pi)
    theta = np.linspace(0.0, np.pi, 40_001)
    meridian = np.stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)], axis=1)
    profile = zonal_matrix(order, np.array([0.0, 0.0, 1.0]), meridian)
    r = auto_window(coeffs, kind)
    assert (profile @ (r.weights * z)).min() >= -2.0 * DEFAULT_TOL * mean
    if kind == "LAPLACIAN":
        weaker = r.param * np.geomspace(1e-4, 1.0 - 1e-3, 300)
    else:
        weaker = r.param * np.geomspace(1.0 + 1e-3, 1e3, 300)
    minima = np.array([(profile @ (window_weights(kind, order, p) * z)).min() for p in weaker])
    assert (minima < -DEFAULT_TOL * mean).all()


def test_auto_window_multichannel():
    # three suns of different strength and direction; every channel must end up >= 0, and for
    # the (monotone here) LAPLACIAN window the result is the strongest single-channel answer
    order = 8
    axes = [AXIS, np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.6, -0.8])]
    zs = [cap_zonal(order, ALPHA, s, 1.0) for s in (1e4, 3e2, 20.0)]
    coeffs = np.stack([sh.zonal_to_coeffs(z, a) for z, a in zip(zs, axes)], axis=1)
    dirs = random_directions(100_000, seed=99)
    for kind in KINDS:
        r = auto_window(coeffs, kind)
        singles = [auto_window(coeffs[:, ch], kind).param for ch in range(3)]
        strongest = max(singles) if kind == "LAPLACIAN" else min(singles)
        assert r.param == pytest.approx(strongest, rel=1e-4)
        for z, a, c0 in zip(zs, axes, coeffs[0]):
            values = zonal_matrix(order, a, dirs) @ (r.weights * z)
            assert values.min() >= -2.0 * DEFAULT_TOL * c0 / math.sqrt(4.0 * np.pi)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("order", [6, 12])
def test_auto_window_two_suns_in_one_channel(kind, order):
    # not zonal: two lights ~48 degrees apart, so the negative lobes are isolated pits rather
    # than rings; check on 200k random directions (through the addition theorem per light)
    a1 = AXIS
    a2 = np.array([0.8, 0.1, 0.6]) / np.linalg.norm([0.8, 0.1, 0.6])
    assert 40 < math.degrees(math.acos(a1 @ a2)) < 60
    z1 = cap_zonal(order, math.radians(8.0), 500.0, 0.5)
    z2 = cap_zonal(order, math.radians(3.0), 2e3, 0.5)
    coeffs = sh.zonal_to_coeffs(z1, a1) + sh.zonal_to_coeffs(z2, a2)
    mean = coeffs[0] / math.sqrt(4.0 * np.pi)
    dirs = random_directions(200_000, seed=77)
    m1, m2 = zonal_matrix(order, a1, dirs), zonal_matrix(order, a2, dirs)

    def values(w):
        return m1 @ (w * z1) + m2 @ (w * z2)

    assert values(np.ones(order)).min() < -0.1 * mean
    r = auto_window(coeffs, kind)
    assert values(r.weights).min() >= -2.0 * DEFAULT_TOL * mean
    weaker = r.param * 0.9 if kind == "LAPLACIAN" else r.param * 1.05
    assert values(window_weights(kind, order, weaker)).min() < -1e-3 * mean


def test_already_non_negative_gets_no_window():
    # von Mises-Fisher lobe exp(2 (axis . x)): positive, and its order-8 truncation stays so
    order = 8
    nodes, wts = np.polynomial.legendre.leggauss(64)
    lobe = np.exp(2.0 * nodes)
    z = np.array(
        [
            2 * np.pi * math.sqrt((2 * l + 1) / (4 * np.pi)) * np.sum(wts * lobe * eval_legendre(l, nodes))
            for l in range(order)
        ]
    )
    coeffs = sh.zonal_to_coeffs(z, AXIS)
    assert (zonal_matrix(order, AXIS, random_directions(20_000, seed=5)) @ z).min() > 0
    for kind, none in (("LAPLACIAN", 0.0), ("HANNING", math.inf), ("LANCZOS", math.inf)):
        r = auto_window(np.stack([coeffs, 2 * coeffs], axis=1), kind)
        assert r.param == none
        assert np.array_equal(r.weights, np.ones(order))
        assert r.iterations == 0
        assert r.min_value_after == r.min_value_before > 0


def test_infeasible_input_raises():
    order = 4
    c = sh.zonal_to_coeffs(cap_zonal(order, ALPHA, SUN, BACKGROUND), AXIS)
    bad = c.copy()
    bad[0] = -abs(bad[0])
    with pytest.raises(ValueError, match="c_0"):
        auto_window(bad)
    zero_mean = c.copy()
    zero_mean[0] = 0.0
    with pytest.raises(ValueError, match=r"channel\(s\) \[1\]"):
        auto_window(np.stack([c, zero_mean], axis=1), "HANNING")
    with pytest.raises(ValueError, match=r"window kind must be one of HANNING, LANCZOS, LAPLACIAN \(got 'NONE'\)"):
        auto_window(c, "NONE")
    # an all-zero channel is identically 0 >= 0: accepted, the other channel decides
    both = auto_window(np.stack([c, np.zeros_like(c)], axis=1), "LAPLACIAN")
    assert both.param == pytest.approx(auto_window(c, "LAPLACIAN").param, rel=1e-12)
