"""The automatic window search: the weakest window of a kind whose reconstruction is non-negative.

See benchmarks/windows/weights.py for the windows themselves and auto_window for the search.
"""

import math
from dataclasses import dataclass

import numpy as np

from prt_addon.core.sh.basis import FOUR_PI, normalize_directions, order_of, sh_basis

from .weights import (
    AUTO_KINDS,
    DEFAULT_TOL,
    _check_kind,
    _real,
    _weights_matrix,
    apply_window,
    sphere_grid,
    window_weights,
)


@dataclass(frozen=True)
class AutoWindowResult:
    """Outcome of auto_window.

    kind             the window kind searched.
    param            the chosen parameter: lambda (LAPLACIAN) or width (HANNING, LANCZOS);
                     "no window" is lambda = 0.0 and width = math.inf.
    weights          (order,) per-band weights, equal to window_weights(kind, order, param).
    min_value_before minimum over all channels of the unwindowed reconstruction,
    min_value_after  and of the windowed one, both over the grid plus the refined minima
                     (in the units of the coefficients, not relative).
    iterations       bisection steps performed (summed over verification rounds).
    """

    kind: str
    param: float
    weights: np.ndarray
    min_value_before: float
    min_value_after: float
    iterations: int


class _Sampler:
    """Per-band partial reconstructions at a growing point set, for one set of channels.

    Stores P[g, c, l] = sum_m y_lm(x_g) c_lm[c] / mean[c]; the windowed, normalised value of
    channel c at x_g is then sum_l P[g, c, l] w_l, an O(order) dot product per point.
    """

    def __init__(self, coeffs, order, scale):
        self.coeffs = coeffs / scale  # (n*n, C): relative to each channel's mean
        self.scale = scale
        self.order = order
        self.points = np.empty((0, 3))
        self.partials = np.empty((0, order))  # rows = (point, channel) pairs

    def partial_sums(self, points):
        n = self.order
        basis = sh_basis(points, n)
        out = np.empty((len(points), self.coeffs.shape[1], n))
        for l in range(n):
            sl = slice(l * l, (l + 1) * (l + 1))
            out[:, :, l] = basis[:, sl] @ self.coeffs[sl]
        return out.reshape(-1, n)

    def add(self, points):
        self.points = np.concatenate([self.points, points])
        self.partials = np.concatenate([self.partials, self.partial_sums(points)])

    def values(self, weights):
        """(G, C) normalised values for (order,) weights."""
        return (self.partials @ weights).reshape(len(self.points), -1)

    def minima(self, weight_matrix):
        """(K,) min over points and channels of the normalised values, (order, K) weights."""
        return (self.partials @ weight_matrix).min(axis=0)

    def raw_min(self, weights):
        return float((self.values(weights) * self.scale).min())


def _cross(a, b):
    return np.stack(
        [
            a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
            a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
            a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0],
        ],
        axis=1,
    )


def _tangent_frames(x):
    helper = np.zeros_like(x)
    near_z = np.abs(x[:, 2]) >= 0.9
    helper[~near_z, 2] = 1.0
    helper[near_z, 0] = 1.0
    e1 = _cross(x, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return e1, _cross(x, e1)


# 3x3 stencil offsets (a, b) in units of the step; index 4 is the centre.
_STENCIL = np.array([(a, b) for a in (-1.0, 0.0, 1.0) for b in (-1.0, 0.0, 1.0)])


def _refine_minima(coeffs, order, seeds, step, min_step):
    """Local minima of v(x) = min_c f_c(x) (coeffs (n*n, C)) near each seed: (points, values).

    A shrinking trust region: each iteration evaluates a 3x3 stencil of half-width `step` in
    the tangent plane and moves to the minimum of the quadratic through it (central
    differences) when its Hessian is positive definite, clamped to `step`, else to the lowest
    stencil point; then step = step * clip(2 |move| / step, 1/16, 1/2). The seeds are the lowest
    grid points, within about one spacing of their minimum, so the total reach (2 * step) is
    enough, and step falls below min_step in <= log2(step / min_step) iterations (14 for the
    1e-4 used). The lowest point ever evaluated is returned, so every returned value is a real
    evaluation whatever the convergence.
    """
    x = seeds.copy()
    steps = np.full(len(x), float(step))
    best_x = x.copy()
    best_v = np.full(len(x), np.inf)
    while True:
        act = np.flatnonzero(steps >= min_step)
        if act.size == 0:
            break
        xa, sa = x[act], steps[act]
        rows = np.arange(act.size)
        e1, e2 = _tangent_frames(xa)
        off = sa[:, None, None] * (_STENCIL[None, :, 0:1] * e1[:, None, :] + _STENCIL[None, :, 1:2] * e2[:, None, :])
        p = xa[:, None, :] + off
        p /= np.linalg.norm(p, axis=2, keepdims=True)
        v = (sh_basis(p.reshape(-1, 3), order) @ coeffs).min(axis=1).reshape(act.size, 9)
        low = v.argmin(axis=1)
        v_low = v[rows, low]
        better = v_low < best_v[act]
        best_v[act[better]] = v_low[better]
        best_x[act[better]] = p[rows, low][better]
        # quadratic model in stencil units: v ~ v0 + g . u + u H u / 2
        ga = 0.5 * (v[:, 7] - v[:, 1])
        gb = 0.5 * (v[:, 5] - v[:, 3])
        haa = v[:, 7] - 2.0 * v[:, 4] + v[:, 1]
        hbb = v[:, 5] - 2.0 * v[:, 4] + v[:, 3]
        hab = 0.25 * (v[:, 8] - v[:, 6] - v[:, 2] + v[:, 0])
        det = haa * hbb - hab * hab
        newton = (haa > 0.0) & (det > 0.0)
        safe = np.where(newton, det, 1.0)
        ua = np.where(newton, -(hbb * ga - hab * gb) / safe, 0.0)
        ub = np.where(newton, -(haa * gb - hab * ga) / safe, 0.0)
        length = np.hypot(ua, ub)
        shrink = np.where(length > 1.0, 1.0 / np.maximum(length, 1e-300), 1.0)
        ua, ub, length = ua * shrink, ub * shrink, np.minimum(length, 1.0)
        y = xa + sa[:, None] * (ua[:, None] * e1 + ub[:, None] * e2)
        y /= np.linalg.norm(y, axis=1, keepdims=True)
        x[act] = np.where(newton[:, None], y, p[rows, low])
        moved = np.where(newton, length, np.where(low == 4, 0.0, 1.0))
        steps[act] = sa * np.clip(2.0 * moved, 1.0 / 16.0, 0.5)
    return best_x, best_v


def _pick_seeds(points, values, spacing, max_seeds=16, pool=512):
    """Lowest points, at least 2 * spacing apart from each other (greedy), up to max_seeds."""
    k = min(pool, len(values))
    idx = np.argpartition(values, k - 1)[:k] if k < len(values) else np.arange(len(values))
    idx = idx[np.argsort(values[idx])]
    cos_sep = math.cos(min(2.0 * spacing, np.pi))
    chosen = []
    for i in idx:
        if all(points[i] @ points[j] < cos_sep for j in chosen):
            chosen.append(i)
            if len(chosen) == max_seeds:
                break
    return points[np.array(chosen, dtype=np.int64)]


SCAN_RATIO = 1.005  # relative step of the dense parameter scan
LAPLACIAN_RANGE = 2.0**-40  # the scan covers lambda_max * [2^-40, 1], then [0, that]
WIDTH_RANGE = 1024.0  # the scan covers widths 1 .. 1024 * order, then [that, inf]


def _scan_strengths(kind, order, s_max, ratio=SCAN_RATIO):
    """Ascending strengths, first 0 (no window), last s_max (known to be feasible).

    Geometric with ratio `ratio` (relative step in the parameter) over lambda_max * [2^-40, 1]
    (LAPLACIAN) or widths [1, 1024 order] (HANNING, LANCZOS, s = 1 / width).
    """
    span = 1.0 / LAPLACIAN_RANGE if kind == "LAPLACIAN" else WIDTH_RANGE * order
    count = int(math.ceil(math.log(span) / math.log(ratio)))
    s = s_max * np.geomspace(1.0 / span, 1.0, count + 1)
    s[-1] = s_max
    return np.concatenate([[0.0], s])


def _first_feasible(sampler, weight_matrix, tol, probes=64, max_rounds=1000):
    """Index of the first column of weight_matrix (n, S) feasible on all sampler points.

    Evaluating every point at every one of the S (~ thousands) scan strengths would cost
    G * C * n * S. Instead keep a small set of witness rows (point, channel): a strength is
    refuted as soon as one witness is negative there. Witnesses start as the most negative
    rows at `probes` evenly spread strengths; the first strength no witness refutes is
    evaluated on every row, and either is the answer or contributes its most negative row as
    a new witness. The answer is exactly the first feasible column, as a full scan would find.
    The last column must be feasible.
    """
    partials_t = np.ascontiguousarray(sampler.partials.T)  # (n, rows)
    count = weight_matrix.shape[1]
    probe = np.unique(np.linspace(0, count - 1, min(probes, count)).round().astype(np.int64))
    witnesses = set((weight_matrix[:, probe].T @ partials_t).argmin(axis=1).tolist())
    for _ in range(max_rounds):
        rows = np.fromiter(witnesses, dtype=np.int64)
        ok = (weight_matrix.T @ partials_t[:, rows] >= -tol).all(axis=1)
        k = int(np.argmax(ok))  # first column no witness refutes (the last one always passes)
        full = weight_matrix[:, k] @ partials_t
        worst = int(np.argmin(full))
        if full[worst] >= -tol:
            return k
        witnesses.add(worst)
    raise RuntimeError("auto_window: witness scan did not converge")  # pragma: no cover


def _search(sampler, kind, order, scan, tol, rtol, max_steps=200):
    """(strength, steps): the first feasible scan strength, bisected against its predecessor.

    Invariant of the bisection: lo infeasible, hi feasible; returns hi.
    """
    k = _first_feasible(sampler, _weights_matrix(kind, order, scan), tol)
    if k == 0:
        return 0.0, 0
    lo, hi = float(scan[k - 1]), float(scan[k])
    steps = 0
    while hi - lo > rtol * hi and steps < max_steps:
        mid = math.sqrt(lo * hi) if lo > 0.0 else 0.5 * hi
        steps += 1
        if sampler.minima(_weights_matrix(kind, order, [mid]))[0] >= -tol:
            hi = mid
        else:
            lo = mid
    return hi, steps


def _laplacian_bound(coeffs, order):
    """Smallest lambda for which the bound below proves every channel non-negative.

    |sum_m c_lm y_lm(x)| <= |c_l| sqrt((2l+1)/(4 pi)) (Cauchy-Schwarz and the addition theorem
    sum_m y_lm(x)^2 = (2l+1)/(4 pi)), and w_l <= 1 / (lambda l^2 (l+1)^2), so bands l >= 1
    together stay below the mean c_0 / sqrt(4 pi) once
        lambda >= max_c sum_{l>=1} |c_l| sqrt(2l+1) / (l^2 (l+1)^2 c_0).
    """
    if order == 1:
        return 0.0
    l = np.arange(1, order)
    band_norm = np.sqrt(np.add.reduceat(coeffs**2, l * l, axis=0))  # (order-1, C)
    terms = band_norm * (np.sqrt(2.0 * l + 1.0) / (l * (l + 1.0)) ** 2)[:, None]
    return float((terms.sum(axis=0) / coeffs[0]).max())


def auto_window(coeffs, kind="LAPLACIAN", grid=None, tol=DEFAULT_TOL, rtol=1e-5, refine=True):
    """Weakest window of `kind` whose reconstruction is non-negative in every channel.

    coeffs  (n*n,) or (n*n, C) float coefficients, any order n >= 1.
    kind    'LAPLACIAN' (weakest = smallest lambda), 'HANNING' or 'LANCZOS' (weakest = largest
            width). Case-insensitive; 'NONE' is rejected (ValueError).
    grid    (G, 3) directions to test; default sphere_grid(n).
    tol     channel c counts as non-negative when min f_c >= -tol * mean_c, where
            mean_c = c_0[c] / sqrt(4 pi) is the channel's average value. The default 1e-6 is
            far below anything visible (half floats resolve ~5e-4 relative) and far above the
            float64 rounding of the reconstruction (the band terms' absolute sum is ~200x the
            mean for a 5 degree 1e4:1 sun at order 16, so rounding is ~1e-13 of the mean): a
            window that makes the function touch zero is decided reliably, not by noise.
    rtol    relative precision of the parameter (bisection stops when hi - lo <= rtol * hi).
    refine  refine the lowest grid points by local search (see below); off = grid-only test.

    Returns AutoWindowResult. No window needed (the unwindowed function passes the test) gives
    param = 0.0 (LAPLACIAN) or math.inf (HANNING, LANCZOS) and all-one weights.

    Infeasible input raises ValueError: windowing keeps the mean c_0, so a channel with
    c_0 <= 0 and any other non-zero coefficient is negative somewhere for every window. A
    channel whose coefficients are all zero is identically 0 and is accepted (ignored).

    Method. The basis is evaluated once on the grid and folded per band, P[g, c, l] =
    sum_m y_lm(x_g) c_lm / mean_c, so the reconstruction for any window is P @ w (O(G C n)).
    The search variable is the strength s = lambda, or s = 1 / width, with s = 0 meaning no
    window; every weight is non-increasing in s. Known feasible ends: width = 1 (only band 0
    is left, the constant mean > 0), and for LAPLACIAN lambda_max = twice the bound
        max_c sum_{l>=1} |c_l| sqrt(2l+1) / (l^2 (l+1)^2 c_0),
    from |sum_m c_lm y_lm(x)| <= |c_l| sqrt((2l+1)/(4 pi)) (addition theorem), at which all
    bands l >= 1 together are at most half the mean. The minimum is NOT monotone in s in
    general (a window is a convolution with a band-limited kernel, which is not non-negative),
    so plain bisection could stop at any sign change. Instead:
      1. scan s = 0 and a dense geometric sequence of strengths, relative step 0.5 %
         (SCAN_RATIO): lambda_max * [2^-40, 1] (~5 600 values) or widths 1 .. 1024 n
         (~2 000 at n = 16), and find the weakest one that passes on every grid point. This
         is exact over the scan but cheap: a small set of "witness" (point, channel) rows
         refutes most strengths, and only the first strength no witness refutes is checked on
         all G * C rows (a failure adds its worst row as a witness; see _first_feasible);
      2. take the weakest feasible scan point and bisect (geometric, arithmetic from 0) between
         it and the infeasible scan point just below it, keeping the invariant lo infeasible,
         hi feasible; return hi. So the result is feasible and the window weaker by rtol is
         not. Feasible "islands" of the parameter do occur (seen with LANCZOS: width 6.445
         feasible, 5.9 .. 6.41 not); one narrower than a scan step (0.5 %) could be missed;
      3. verify: from the 16 lowest grid points at least 2 grid spacings apart, search the
         local minima of the chosen reconstruction (3x3 stencil in the tangent plane, Newton
         steps on its quadratic, down to 1e-4 of the grid spacing; _refine_minima). If one is
         below the tolerance, add the refined points to the test set and redo 1-2, until
         verified (typically 1 or 2 rounds). The refined points stay in the test set, so the
         result passes on the grid and at the true minima found near its lowest points.
    The grid spacing (sphere_grid) makes a missed lobe unlikely but not impossible; the
    refinement removes the grid's error for the lobes it sees. Cost (one core of an AMD EPYC
    server, 1-3 channels, see docs/windows.md): 7-12 ms at order 4, 7-19 ms at order 8,
    21-62 ms at order 16.
    """
    kind = _check_kind(kind, AUTO_KINDS)
    c = np.asarray(coeffs, dtype=np.float64)
    if c.ndim not in (1, 2):
        raise ValueError(f"coeffs must have shape (n*n,) or (n*n, C), got {c.shape}")
    order = order_of(c.shape[0])
    if not np.isfinite(c).all():
        raise ValueError("coeffs contain NaN or inf")
    tol = _real(tol, "tol")
    rtol = _real(rtol, "rtol")
    if not tol >= 0.0 or not (0.0 < rtol < 1.0):
        raise ValueError("tol must be >= 0 and 0 < rtol < 1")
    c2 = c.reshape(order * order, -1)

    nonzero = np.any(c2 != 0.0, axis=0)
    bad = np.flatnonzero(nonzero & (c2[0] <= 0.0))
    if bad.size:
        raise ValueError(
            f"no window can make channel(s) {bad.tolist()} non-negative: c_0 <= 0 "
            f"(c_0 = {c2[0, bad].tolist()}); windows keep c_0, the channel's mean times "
            "sqrt(4 pi), and a zero- or negative-mean function is negative somewhere"
        )
    no_window = 0.0 if kind == "LAPLACIAN" else math.inf
    if not nonzero.any():
        return AutoWindowResult(kind, no_window, np.ones(order), 0.0, 0.0, 0)
    c2 = c2[:, nonzero]
    scale = c2[0] / math.sqrt(FOUR_PI)

    if grid is None:
        grid = sphere_grid(order)
    else:
        grid = normalize_directions(grid)
        if len(grid) == 0:
            raise ValueError("grid must hold at least one direction")
    spacing = math.sqrt(FOUR_PI / max(len(grid), 1))

    if kind == "LAPLACIAN":
        s_max = 2.0 * _laplacian_bound(c2, order)  # 2x: the rest is <= mean / 2 there
        if s_max == 0.0:  # bands >= 1 all zero: a positive constant, no window needed
            s_max = 1.0
    else:
        s_max = 1.0  # width 1: only band 0, the (positive) mean, is left
    scan = _scan_strengths(kind, order, s_max)

    sampler = _Sampler(c2, order, scale)
    sampler.add(grid)
    steps_total = 0
    for _ in range(50):
        s, steps = _search(sampler, kind, order, scan, tol, rtol)
        steps_total += steps
        param = no_window if s == 0.0 else (s if kind == "LAPLACIAN" else 1.0 / s)
        weights = window_weights(kind, order, param)
        if not refine:
            break
        v = sampler.values(weights).min(axis=1)
        seeds = _pick_seeds(sampler.points, v, spacing)
        cw = apply_window(sampler.coeffs, weights)
        pts, vals = _refine_minima(cw, order, seeds, spacing, 1e-4 * spacing)
        sampler.add(pts)
        if vals.min() >= -tol:
            break
    else:  # pragma: no cover - never seen; would mean the refinement keeps finding new lobes
        raise RuntimeError("auto_window: verification did not converge")

    return AutoWindowResult(
        kind=kind,
        param=float(param),
        weights=weights,
        min_value_before=sampler.raw_min(np.ones(order)),
        min_value_after=sampler.raw_min(weights),
        iterations=steps_total,
    )
