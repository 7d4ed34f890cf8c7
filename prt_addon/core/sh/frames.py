"""The object's local frame of a transfer: the rotation part of a transform, and SH into it."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..serial_blas import matmul_serial
from .basis import order_of
from .rotation import band_matrices


def frame_rotation(linear: npt.ArrayLike) -> tuple[np.ndarray, bool]:
    """(R, mirrored): the rotation part of a 3x3 matrix by polar decomposition.

    linear = Q S with Q orthogonal; R = Q when det Q > 0. For a mirroring matrix (det Q < 0)
    R = -Q is a proper rotation and `mirrored` is True: Q w = R (-w).
    """
    u, _s, vt = np.linalg.svd(np.asarray(linear, dtype=np.float64)[:3, :3])
    q = u @ vt
    if np.linalg.det(q) < 0:
        return -q, True
    return q, False


def to_local_frame(coeffs: npt.ArrayLike, linear: npt.ArrayLike) -> np.ndarray:
    """World-frame transfer (P, n*n) -> coefficients of t_local(u) = t_world(Q u).

    Q is the orthogonal polar factor of `linear` (the object's matrix_world, 3x3 part). With
    Q = R a rotation this is rotation_matrix(R^-1) applied to each row. With Q = -R (negative
    scale) the odd bands are negated too, because t_world(-R u) is the point reflection of
    t_world rotated by R^-1, and a point reflection multiplies band l by (-1)^l.
    """

    coeffs = np.asarray(coeffs)
    order = order_of(coeffs.shape[1])
    r, mirrored = frame_rotation(linear)
    # rotation_matrix(R^-1) is block-diagonal by band: one (2l+1)^2 product per band (order^4 ->
    # ~order^3 / 3 multiplications per row); mirrored, band l is also scaled by (-1)^l.
    blocks = band_matrices(r.T, order)
    band_t = [np.ascontiguousarray(block.T * (-1.0 if mirrored and l % 2 else 1.0)) for l, block in enumerate(blocks)]
    bands = [slice(l * l, (l + 1) * (l + 1)) for l in range(order)]
    out = np.empty(coeffs.shape, dtype=coeffs.dtype)
    # float64 maths in blocks of 1024 rows through two reused buffers (fresh multi-megabyte
    # temporaries cost more in page faults than the product), with serial BLAS calls.
    rows = 1024
    block, product = np.empty((rows, coeffs.shape[1])), np.empty((rows, coeffs.shape[1]))
    for r0 in range(0, len(coeffs), rows):
        n = min(rows, len(coeffs) - r0)
        block[:n] = coeffs[r0 : r0 + n]
        for b, mb_t in zip(bands, band_t):
            matmul_serial(block[:n, b], mb_t, out=product[:n, b])
        out[r0 : r0 + n] = product[:n]
    return out
