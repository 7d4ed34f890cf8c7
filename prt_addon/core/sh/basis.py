"""Real orthonormal spherical harmonics, any order, float64.

Conventions (used by every module of the add-on):

* Axes are Blender's world axes, Z up. A direction is (x, y, z); theta is measured from +Z,
  phi = atan2(y, x).
* "order" n means bands l = 0 .. n-1, i.e. n*n coefficients; coefficient index i = l(l+1) + m.
* No Condon-Shortley phase: every basis function is positive somewhere along +X, +Y or +Z,
  so band 1 is (y_{1,-1}, y_{1,0}, y_{1,1}) = sqrt(3/(4 pi)) * (y, z, x), as in Sloan's
  "Stupid Spherical Harmonics Tricks" and Ramamoorthi & Hanrahan (2001).
  y_{l,0}  = K_l^0 P_l(cos theta)
  y_{l,m}  = sqrt(2) K_l^m P_l^m(cos theta) cos(m phi)     (m > 0)
  y_{l,-m} = sqrt(2) K_l^m P_l^m(cos theta) sin(m phi)     (m > 0)
  with K_l^m = sqrt((2l+1)/(4 pi) (l-m)!/(l+m)!) and P_l^m without the (-1)^m factor.

Evaluation never forms factorials. With Q_l^m = K_l^m P_l^m(z) / sin^m(theta), a polynomial in z,
the fully normalised recurrences (e.g. Holmes & Featherstone 2002, J. Geodesy 76) are

  Q_0^0 = 1/sqrt(4 pi),  Q_m^m = sqrt((2m+1)/(2m)) Q_{m-1}^{m-1},  Q_{m+1}^m = sqrt(2m+3) z Q_m^m,
  Q_l^m = a_lm (z Q_{l-1}^m - b_lm Q_{l-2}^m),
  a_lm = sqrt((4l^2-1)/(l^2-m^2)),  b_lm = sqrt(((l-1)^2-m^2)/(4(l-1)^2-1)),

and sin^m(theta) (cos m phi, sin m phi) = (Re, Im) of (x + i y)^m, a polynomial in x and y.
Both factors are polynomials, so the basis is exact at the poles and needs no atan2.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import numpy.typing as npt

FOUR_PI = 4.0 * np.pi


def num_coeffs(order: int) -> int:
    """Number of coefficients of an order-n expansion (bands 0..n-1)."""
    return order * order


def sh_index(l: int, m: int) -> int:
    """Flat coefficient index of band l, degree m (|m| <= l)."""
    return l * (l + 1) + m


def band_of_index(order: int) -> np.ndarray:
    """(order**2,) array: the band l of each coefficient index."""
    return np.repeat(np.arange(order), 2 * np.arange(order) + 1)


def check_order(order: int) -> int:
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order < 1:
        raise ValueError(f"SH order must be an integer >= 1 (got {order!r})")
    return int(order)


def normalize_directions(directions: npt.ArrayLike) -> np.ndarray:
    """(N, 3) float64 unit vectors; raises ValueError on zero-length or non-finite input."""
    d = np.asarray(directions, dtype=np.float64)
    if d.ndim != 2 or d.shape[1] != 3:
        raise ValueError(f"directions must have shape (N, 3), got {d.shape}")
    # Scale by the largest component first so that lengths near the float64 limits
    # (1e-300, 1e300) neither underflow nor overflow when squared.
    big = np.max(np.abs(d), axis=1)
    bad = ~np.isfinite(big) | (big == 0.0)
    if bad.any():
        raise ValueError(f"{int(bad.sum())} of {len(d)} directions are zero-length or not finite")
    d = d / big[:, None]
    return d / np.sqrt(np.einsum("ij,ij->i", d, d))[:, None]


def legendre_columns(z: npt.ArrayLike, order: int) -> Iterator[tuple[int, int, np.ndarray]]:
    """Yield (l, m, Q_l^m(z)) for 0 <= m <= l < order, m-major, Q as defined in the module doc.

    z is a float64 array of cos(theta); the yielded arrays are fresh (safe to keep).
    """
    z = np.asarray(z, dtype=np.float64)
    q_mm = np.full_like(z, 1.0 / np.sqrt(FOUR_PI))
    for m in range(order):
        if m > 0:
            q_mm = q_mm * np.sqrt((2.0 * m + 1.0) / (2.0 * m))
        yield m, m, q_mm
        if m + 1 >= order:
            continue
        q_prev2 = q_mm
        q_prev1 = np.sqrt(2.0 * m + 3.0) * z * q_mm
        yield m + 1, m, q_prev1
        for l in range(m + 2, order):
            a = np.sqrt((4.0 * l * l - 1.0) / (l * l - m * m))
            b = np.sqrt(((l - 1.0) ** 2 - m * m) / (4.0 * (l - 1.0) ** 2 - 1.0))
            q_l = a * (z * q_prev1 - b * q_prev2)
            yield l, m, q_l
            q_prev2, q_prev1 = q_prev1, q_l


def azimuthal_powers(x: npt.ArrayLike, y: npt.ArrayLike, order: int) -> tuple[np.ndarray, np.ndarray]:
    """(cos_part, sin_part), each (order, N): Re and Im of (x + i y)^m for m = 0..order-1."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    c = np.empty((order,) + x.shape)
    s = np.empty((order,) + x.shape)
    c[0] = 1.0
    s[0] = 0.0
    for m in range(1, order):
        c[m] = x * c[m - 1] - y * s[m - 1]
        s[m] = x * s[m - 1] + y * c[m - 1]
    return c, s


def sh_basis(directions: npt.ArrayLike, order: int) -> np.ndarray:
    """Real SH basis at unit directions: (N, order**2) float64.

    Directions are normalised first; zero-length or non-finite ones raise ValueError.
    """
    order = check_order(order)
    d = normalize_directions(directions)
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    # Filled coefficient-major (contiguous rows) and returned transposed: writing columns of an
    # (N, n*n) C-ordered array is several times slower.
    out = np.empty((order * order, len(d)))
    cos_m, sin_m = azimuthal_powers(x, y, order)
    cos_m[1:] *= np.sqrt(2.0)
    sin_m[1:] *= np.sqrt(2.0)
    for l, m, q in legendre_columns(z, order):
        if m == 0:
            out[sh_index(l, 0)] = q
        else:
            np.multiply(q, cos_m[m], out=out[sh_index(l, m)])
            np.multiply(q, sin_m[m], out=out[sh_index(l, -m)])
    return out.T


# Directions evaluated at a time by evaluate(): bounds its temporary basis to CHUNK * n*n floats.
EVALUATE_CHUNK = 32768


def evaluate(coeffs: npt.ArrayLike, directions: npt.ArrayLike) -> np.ndarray:
    """Evaluate an expansion at directions. coeffs (n*n,) or (n*n, C) -> (N,) or (N, C)."""
    coeffs = np.asarray(coeffs, dtype=np.float64)
    order = order_of(coeffs.shape[0])
    directions = np.asarray(directions, dtype=np.float64)
    out = np.empty((len(directions),) + coeffs.shape[1:])
    for start in range(0, len(directions), EVALUATE_CHUNK):
        chunk = slice(start, start + EVALUATE_CHUNK)
        out[chunk] = sh_basis(directions[chunk], order) @ coeffs
    return out


def convolve_zonal(coeffs: npt.ArrayLike, zonal: npt.ArrayLike) -> np.ndarray:
    """Coefficients of the convolution of f with a zonal kernel h (Funk-Hecke theorem).

    (f * h)(n) = integral f(w) h(n . w) dw has coefficients sqrt(4 pi / (2l+1)) z_l c_lm, where
    z_l are h's zonal coefficients. With h = max(0, cos)/pi this turns radiance into the
    unshadowed diffuse radiance E/pi (Ramamoorthi & Hanrahan 2001).
    """
    coeffs = np.asarray(coeffs, dtype=np.float64)
    order = order_of(coeffs.shape[0])
    bands = band_of_index(order)
    scale = np.sqrt(FOUR_PI / (2.0 * bands + 1.0)) * np.asarray(zonal, dtype=np.float64)[bands]
    return coeffs * (scale if coeffs.ndim == 1 else scale[:, None])


def order_of(num: int) -> int:
    """The order n whose n*n equals num; ValueError if num is not a perfect square."""
    n = int(round(np.sqrt(num)))
    if n < 1 or n * n != num:
        raise ValueError(f"{num} coefficients is not a square number (order**2)")
    return n


def zonal_to_coeffs(zonal: npt.ArrayLike, axis: npt.ArrayLike) -> np.ndarray:
    """Coefficients of a function symmetric about `axis` with zonal coefficients z_l.

    Rotating a zonal function (Sloan 2008, eq. 14): c_lm = sqrt(4 pi / (2l+1)) z_l y_lm(axis).
    zonal has shape (order,) or (order, C); the result (order**2,) or (order**2, C).
    """
    zonal = np.asarray(zonal, dtype=np.float64)
    order = zonal.shape[0]
    y = sh_basis(np.asarray(axis, dtype=np.float64).reshape(1, 3), order)[0]
    bands = band_of_index(order)
    scale = np.sqrt(FOUR_PI / (2.0 * bands + 1.0)) * y
    if zonal.ndim == 1:
        return scale * zonal[bands]
    return scale[:, None] * zonal[bands]
