"""Rotation of real SH coefficient vectors by any 3x3 rotation, at any order.

`rotation_matrix(R, n)` returns the block-diagonal (n*n, n*n) matrix M with M @ c = coefficients
of the rotated function g(w) = f(R^-1 w); i.e. sum_i (M c)_i y_i(w) = sum_i c_i y_i(R^T w).

Blocks are built band by band with the recurrence of Ivanic & Ruedenberg, "Rotation Matrices for
Real Spherical Harmonics. Direct Determination by Recursion", J. Phys. Chem. 100 (1996) 6342, with
the corrections of J. Phys. Chem. A 102 (1998) 9099. The recurrence uses only products and sums
of the previous band's entries with bounded coefficients, so it is stable in float64 to high
order (orthogonality error ~1e-13 at l = 64). Each band is computed with numpy over all (m, n)
pairs at once.

Band 1 is the 3x3 rotation itself, permuted to (y, z, x) because y_{1,(-1,0,1)} ~ (y, z, x)
(see sh.py: no Condon-Shortley phase).

Rotation about Z has a closed form (fast path, `z_rotation_matrix`): in band l, the pair
(y_{l,-m}, y_{l,m}) turns by the angle m * alpha.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable

import numpy as np
import numpy.typing as npt

from .basis import check_order, order_of

_BAND1_ORDER = (1, 2, 0)  # y, z, x


def _as_rotation(rotation):
    r = np.asarray(rotation, dtype=np.float64)
    if r.shape != (3, 3) or not np.all(np.isfinite(r)):
        raise ValueError(f"rotation must be a finite 3x3 matrix, got shape {r.shape}")
    if np.abs(r @ r.T - np.eye(3)).max() > 1e-6 or np.linalg.det(r) < 0:
        raise ValueError("rotation must be a proper orthogonal matrix (R R^T = I, det R = +1)")
    return r


def band_matrices(rotation: npt.ArrayLike, order: int) -> list[np.ndarray]:
    """List of per-band rotation blocks [(1x1), (3x3), ..., (2n-1 x 2n-1)], indices m = -l..l."""
    order = check_order(order)
    r = _as_rotation(rotation)
    blocks = [np.ones((1, 1))]
    if order == 1:
        return blocks
    r1 = r[np.ix_(_BAND1_ORDER, _BAND1_ORDER)]
    blocks.append(r1)
    for l in range(2, order):
        blocks.append(_next_band(r1, blocks[-1], l))
    return blocks


@functools.lru_cache(maxsize=None)
def _band_plan(l):
    """Band l of the recurrence as a fixed linear plan (depends on l only, so it is cached).

    Every entry (m, n) of band l is sum_t coef_t * r1[i_t, j_t] * prev[a_t, b_t] over 10 terms:
    u U + v V + w W, where each of U, V, W is one or two of Ivanic-Ruedenberg's P(i, l, a, b)
    functions and each P is at most two products r1 * prev. Returned as (coef, r1_flat, prev_flat),
    each (10, 2l+1, 2l+1), with flat indices into r1 (3x3) and prev ((2l-1) x (2l-1)).
    """
    size = 2 * l + 1
    m = np.repeat(np.arange(-l, l + 1)[:, None], size, axis=1)
    n = m.T.copy()
    abs_m = np.abs(m)
    delta_m0 = (m == 0).astype(np.float64)
    d_m1 = (m == 1).astype(np.float64)
    d_mm1 = (m == -1).astype(np.float64)

    denom = np.where(np.abs(n) < l, (l + n) * (l - n), 2 * l * (2 * l - 1)).astype(np.float64)
    u = np.sqrt((l + m) * (l - m) / denom)
    v = 0.5 * np.sqrt((1.0 + delta_m0) * (l + abs_m - 1) * (l + abs_m) / denom) * (1.0 - 2.0 * delta_m0)
    w = -0.5 * np.sqrt(np.clip((l - abs_m - 1) * (l - abs_m), 0, None) / denom) * (1.0 - delta_m0)

    def prev_flat(a, b):
        # Out-of-range (a, b) only occur where the term's coefficient is 0: clip to stay in bounds.
        a = np.clip(a, -(l - 1), l - 1) + (l - 1)
        b = np.clip(b, -(l - 1), l - 1) + (l - 1)
        return a * (2 * l - 1) + b

    def p_terms(i, a, b):
        """P(i, l, a, b) as two terms (sign, r1 flat index, prev flat index)."""
        row = (i + 1) * 3
        top, bottom = b == l, b == -l
        sign0 = np.ones_like(a, dtype=np.float64)
        r1_0 = np.where(top | bottom, row + 2, row + 1)
        prev_0 = np.where(top, prev_flat(a, l - 1), np.where(bottom, prev_flat(a, -l + 1), prev_flat(a, b)))
        sign1 = np.where(top, -1.0, np.where(bottom, 1.0, 0.0))
        r1_1 = np.full_like(a, row + 0)
        prev_1 = np.where(top, prev_flat(a, -l + 1), prev_flat(a, l - 1))
        return [(sign0, r1_0, prev_0), (sign1, r1_1, prev_1)]

    def scaled(factor, terms):
        return [(factor * sign, r1, prev) for sign, r1, prev in terms]

    pos, neg, zero = (m > 0), (m < 0), (m == 0)
    # V: m > 0: P(1, m-1) sqrt(1 + d_m1) - P(-1, -m+1)(1 - d_m1)
    #    m < 0: P(1, m+1)(1 - d_mm1) + P(-1, -m-1) sqrt(1 + d_mm1)
    #    m = 0: P(1, 1) + P(-1, -1)
    v_first_a = np.where(pos, m - 1, np.where(neg, m + 1, 1))
    v_first_f = np.where(pos, np.sqrt(1.0 + d_m1), np.where(neg, 1.0 - d_mm1, 1.0))
    v_second_a = np.where(pos, -m + 1, np.where(neg, -m - 1, -1))
    v_second_f = np.where(pos, -(1.0 - d_m1), np.where(neg, np.sqrt(1.0 + d_mm1), 1.0))
    # W: m > 0: P(1, m+1) + P(-1, -m-1);  m < 0: P(1, m-1) - P(-1, -m+1);  m = 0: 0 (w = 0)
    w_first_a = np.where(pos, m + 1, m - 1)
    w_second_a = np.where(pos, -m - 1, -m + 1)
    w_second_f = np.where(pos, 1.0, np.where(neg, -1.0, 0.0))

    terms = (
        scaled(u, p_terms(0, m, n))
        + scaled(v * v_first_f, p_terms(1, v_first_a, n))
        + scaled(v * v_second_f, p_terms(-1, v_second_a, n))
        + scaled(w * (1.0 - zero), p_terms(1, w_first_a, n))
        + scaled(w * w_second_f, p_terms(-1, w_second_a, n))
    )
    coef = np.stack([t[0] for t in terms])
    r1_index = np.stack([t[1] for t in terms])
    prev_index = np.stack([t[2] for t in terms])
    return coef, r1_index, prev_index


def _next_band(r1, prev, l):
    """Band l from band 1 (r1, indexed -1..1 as 0..2) and band l-1 (prev, indexed -(l-1)..l-1)."""
    coef, r1_index, prev_index = _band_plan(l)
    return np.einsum("tij,tij,tij->ij", coef, r1.ravel()[r1_index], prev.ravel()[prev_index])


def block_diagonal(blocks: list[np.ndarray]) -> np.ndarray:
    order = len(blocks)
    out = np.zeros((order * order, order * order))
    for l, block in enumerate(blocks):
        s = l * l
        out[s : s + 2 * l + 1, s : s + 2 * l + 1] = block
    return out


def rotation_matrix(rotation: npt.ArrayLike, order: int) -> np.ndarray:
    """(order**2, order**2) matrix M such that M @ c are the coefficients of f(R^-1 w)."""
    return block_diagonal(band_matrices(rotation, order))


def rotate(coeffs: npt.ArrayLike, rotation: npt.ArrayLike) -> np.ndarray:
    """Coefficients of f(R^-1 w) for coeffs (n*n,) or (n*n, C), applying the blocks band by band."""

    coeffs = np.asarray(coeffs, dtype=np.float64)
    order = order_of(coeffs.shape[0])
    out = np.empty_like(coeffs)
    for l, block in enumerate(band_matrices(rotation, order)):
        s = slice(l * l, (l + 1) * (l + 1))
        out[s] = block @ coeffs[s]
    return out


@functools.lru_cache(maxsize=None)
def _degree_pairs(order):
    """Index arrays of the degree m of each coefficient and of its partner (l, -m)."""
    bands = np.arange(order * order)
    l = np.floor(np.sqrt(bands)).astype(int)
    m = bands - l * (l + 1)
    return m, l * (l + 1) - m


def z_rotation_matrix(angle: float, order: int) -> np.ndarray:
    """Closed form of rotation_matrix(Rz(angle), order): per band, (y_{l,-m}, y_{l,m}) turn by m*angle.

    Rotating f by alpha about Z shifts its phi dependence: cos(m (phi - alpha)) and
    sin(m (phi - alpha)) expand into the pair with cos(m alpha) and sin(m alpha).
    """
    order = check_order(order)
    m, partner = _degree_pairs(order)
    out = np.zeros((order * order, order * order))
    index = np.arange(order * order)
    out[index, index] = np.cos(m * angle)
    out[index, partner] += np.where(m > 0, -1.0, 1.0) * np.sin(np.abs(m) * angle) * (m != 0)
    return out


def rotate_z(coeffs: npt.ArrayLike, angle: float) -> np.ndarray:
    """rotate(coeffs, Rz(angle)) without forming a matrix: O(n*n) instead of O(n^3)."""

    coeffs = np.asarray(coeffs, dtype=np.float64)
    m, partner = _degree_pairs(order_of(coeffs.shape[0]))
    c = np.cos(m * angle)
    s = np.where(m > 0, -1.0, 1.0) * np.sin(np.abs(m) * angle)
    if coeffs.ndim > 1:
        c, s = c[:, None], s[:, None]
    return c * coeffs + s * coeffs[partner]


def axis_angle_matrix(axis: npt.ArrayLike, angle: float) -> np.ndarray:
    """3x3 rotation by `angle` (radians, right-handed) about `axis` (Rodrigues' formula)."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * (k @ k)


def euler_xyz_matrix(angles: Iterable[float] | np.ndarray) -> np.ndarray:
    """3x3 matrix of Blender's 'XYZ' Euler rotation (applied X first, then Y, then Z): Rz Ry Rx."""
    x, y, z = (float(a) for a in angles)
    return axis_angle_matrix((0, 0, 1), z) @ axis_angle_matrix((0, 1, 0), y) @ axis_angle_matrix((1, 0, 0), x)
