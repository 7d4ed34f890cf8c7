"""SH coefficients of analytic functions, used as references by tests and benchmarks.

Both functions are zonal (symmetric about an axis), so they are computed from their zonal
coefficients z_l = 2 pi integral_{-1}^{1} f(x) Q_l^0(x) dx and placed on the axis with
sh.zonal_to_coeffs. The integrals are polynomial and evaluated exactly by Gauss-Legendre
quadrature on the interval where f is non-zero, which stays accurate for tiny sun disks where the
closed form (P_{l-1}(cos a) - P_{l+1}(cos a)) / (2l + 1) loses digits to cancellation.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from .basis import check_order, legendre_columns, zonal_to_coeffs


def _zonal_integral(order, lo, hi, weight_power):
    """z_l = 2 pi integral_lo^hi x^weight_power Q_l^0(x) dx for l < order (exact for polynomials)."""
    nodes, weights = np.polynomial.legendre.leggauss(order // 2 + 2)
    x = 0.5 * (hi - lo) * nodes + 0.5 * (hi + lo)
    w = 0.5 * (hi - lo) * weights * x**weight_power
    zonal = np.zeros(order)
    for l, m, q in legendre_columns(x, order):
        if m == 0:
            zonal[l] = 2.0 * np.pi * (w @ q)
    return zonal


def clamped_cosine_zonal(order: int) -> np.ndarray:
    """Zonal coefficients of max(0, cos theta) / pi: 0.2820948, 0.3257350, 0.1576958, 0, ..."""
    return _zonal_integral(check_order(order), 0.0, 1.0, 1) / np.pi


def clamped_cosine_coeffs(order: int, normal: npt.ArrayLike = (0.0, 0.0, 1.0)) -> np.ndarray:
    """(order**2,) coefficients of the diffuse transfer max(0, n . w) / pi about `normal`."""
    return zonal_to_coeffs(clamped_cosine_zonal(order), normal)


def cap_zonal(order: int, half_angle: float) -> np.ndarray:
    """Zonal coefficients of the indicator of a spherical cap of angular radius half_angle."""
    if not 0.0 <= half_angle <= np.pi:
        raise ValueError(f"cap half angle must be in [0, pi], got {half_angle}")
    return _zonal_integral(check_order(order), float(np.cos(half_angle)), 1.0, 0)


def cap_coeffs(order: int, axis: npt.ArrayLike, half_angle: float, radiance: npt.ArrayLike = 1.0) -> np.ndarray:
    """Coefficients of a sun disk: constant `radiance` (scalar or RGB) inside the cap, 0 outside."""
    zonal = cap_zonal(order, half_angle)
    radiance = np.asarray(radiance, dtype=np.float64)
    return zonal_to_coeffs(zonal[:, None] * radiance[None, :] if radiance.ndim else zonal * radiance, axis)
