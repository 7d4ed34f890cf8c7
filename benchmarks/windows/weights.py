"""Windows against SH ringing (Gibbs oscillations), with an automatic, verified parameter search.

A truncated SH expansion of a function with a sharp feature (a sun, a bright window, a shadow
edge) oscillates around it and can go negative, which shows up as dark or even negative light.
A *window* scales band l of a coefficient vector by a factor w_l (w_0 = 1, so the mean is
kept). That is a convolution with a zonal kernel, so it commutes with rotation and is the same
for every m of a band.

Kinds (l = band, n = order, i.e. bands 0 .. n-1):

* ``NONE``: w_l = 1.
* ``HANNING`` (P.-P. Sloan, "Stupid Spherical Harmonics (SH) Tricks", GDC 2008, section on
  windowing): w_l = (1 + cos(pi l / width)) / 2 for l < width, 0 otherwise.
* ``LANCZOS`` (Lanczos sigma factors, same source): w_l = sinc(l / width)
  = sin(pi l / width) / (pi l / width) for l < width, 0 otherwise (w_0 = 1).
* ``LAPLACIAN`` (P.-P. Sloan, "Deringing Spherical Harmonics", SIGGRAPH Asia 2017 Technical
  Briefs): w_l = 1 / (1 + lambda l^2 (l+1)^2). It is the exact minimiser of
  ||g - f||^2 + lambda ||Laplacian g||^2 over expansions g: the spherical Laplacian scales
  y_lm by -l(l+1) and the basis is orthonormal, so the functional decouples per coefficient
  into (g_lm - f_lm)^2 + lambda l^2 (l+1)^2 g_lm^2.

Width convention (Hanning, Lanczos). ``width`` is a real number > 0 in band units; the window
is zero from band ``width`` on. Both formulas are already 0 at l = width, so writing the
condition as "l < width" or "l <= width" gives identical weights. Sloan relates the width to
the order of the expansion (as summarised secondhand: width = order); our default is
``width = order``: the last kept band l = n-1 still gets a positive weight (Hanning at n = 3:
1, 0.75, 0.25), while width = order - 1 would zero it.
``width = inf`` means no window (all ones); for width <= 1 only band 0 survives.

Automatic mode (:func:`auto_window`) picks the weakest window of a kind whose reconstruction
is non-negative in every colour channel, at any order (Filament's ``cmgen`` auto windowing -
which uses a sinc^4 window and Sloan's closed-form minimum of a 3-band expansion - is limited to
3 bands). See :func:`auto_window` for the search and its guarantees.

Pure numpy, float64. Never imports bpy or scipy.
"""

import math

import numpy as np

from prt_addon.core.sh.basis import band_of_index, check_order, order_of

KINDS = ("NONE", "HANNING", "LANCZOS", "LAPLACIAN")
AUTO_KINDS = ("HANNING", "LANCZOS", "LAPLACIAN")

# Default relative tolerance of the non-negativity test, see auto_window.
DEFAULT_TOL = 1e-6


def _check_kind(kind, allowed=KINDS):
    k = kind.upper() if isinstance(kind, str) else None
    if k not in allowed:
        raise ValueError(f"window kind must be one of {', '.join(allowed)} (got {kind!r})")
    return k


def _real(value, what):
    if isinstance(value, bool):
        raise ValueError(f"{what} must be a real number (got {value!r})")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be a real number (got {value!r})") from None
    if math.isnan(v):
        raise ValueError(f"{what} must not be NaN")
    return v


def _weights_matrix(kind, order, strengths):
    """(order, K) weights for K strengths s (the search variable of auto_window).

    s = lambda for LAPLACIAN, s = 1 / width for HANNING and LANCZOS; s = 0 is "no window" and
    every weight is non-increasing in s.
    """
    s = np.asarray(strengths, dtype=np.float64)[None, :]
    l = np.arange(order, dtype=np.float64)[:, None]
    if kind == "LAPLACIAN":
        return 1.0 / (1.0 + s * (l * (l + 1.0)) ** 2)
    x = l * s
    inside = x < 1.0
    if kind == "HANNING":
        return np.where(inside, 0.5 * (1.0 + np.cos(np.pi * x)), 0.0)
    return np.where(inside, np.sinc(x), 0.0)  # np.sinc(x) = sin(pi x) / (pi x), sinc(0) = 1


def window_weights(kind, order, param=None):
    """Per-band weights w_l, l = 0 .. order-1, as an (order,) float64 array; w_0 = 1 always.

    kind  'NONE'      w_l = 1; param is ignored.
          'HANNING'   w_l = (1 + cos(pi l / width)) / 2 for l < width, else 0   (Sloan 2008)
          'LANCZOS'   w_l = sin(pi l / width) / (pi l / width) for l < width, else 0
          'LAPLACIAN' w_l = 1 / (1 + lambda l^2 (l+1)^2)                     (Sloan 2017)
    param HANNING / LANCZOS: width, a real > 0 (inf allowed = no window); None -> width = order,
          so the last band is still weighted > 0.
          LAPLACIAN: lambda, a finite real >= 0 (0 = no window). Required: a good lambda depends
          on the data (its scale goes like 1 / order^4), use auto_window to choose one.
    kind is case-insensitive; a bad kind or parameter raises ValueError.
    """
    kind = _check_kind(kind)
    order = check_order(order)
    if kind == "NONE":
        return np.ones(order)
    if kind == "LAPLACIAN":
        if param is None:
            raise ValueError(
                "the LAPLACIAN window needs lambda (>= 0); there is no data-independent "
                "default - use auto_window() to choose one"
            )
        lam = _real(param, "lambda")
        if not (0.0 <= lam < math.inf):
            raise ValueError(f"lambda must be finite and >= 0 (got {lam!r})")
        return _weights_matrix(kind, order, [lam])[:, 0]
    width = float(order) if param is None else _real(param, "width")
    if not width > 0.0:
        raise ValueError(f"width must be > 0 (got {width!r})")
    if math.isinf(width):
        return np.ones(order)
    l = np.arange(order, dtype=np.float64)
    x = l / width
    if kind == "HANNING":
        w = np.where(x < 1.0, 0.5 * (1.0 + np.cos(np.pi * x)), 0.0)
    else:
        w = np.where(x < 1.0, np.sinc(x), 0.0)
    w[0] = 1.0
    return w


def apply_window(coeffs, weights):
    """Scale band l of coeffs by weights[l]: (n*n,) or (n*n, C) -> new float64 array, same shape.

    weights must have shape (n,), n the order of coeffs (ValueError otherwise).
    """
    c = np.asarray(coeffs, dtype=np.float64)
    if c.ndim not in (1, 2):
        raise ValueError(f"coeffs must have shape (n*n,) or (n*n, C), got {c.shape}")
    order = order_of(c.shape[0])
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != (order,):
        raise ValueError(f"weights must have shape ({order},) for order {order}, got {w.shape}")
    scale = w[band_of_index(order)]
    return c * scale if c.ndim == 1 else c * scale[:, None]


def sphere_grid(order, density=6.0):
    """(G, 3) unit directions on which to look for the negative lobes of an order-n expansion.

    Latitude rings theta_i = i h, i = 0 .. R, with h = pi / R and R = max(ceil(density * order),
    16); ring i holds max(1, round(2 pi sin(theta_i) / h)) points, equally spaced in phi and
    staggered by half a step on odd rings. The poles (0, 0, +-1) are exact members (rings 0
    and R) and neighbouring points are about h apart everywhere, G ~ 4 R^2 / pi.

    Why h = pi / (6 n) by default: the shortest oscillation of an order-n expansion (band n-1)
    has half-wavelength ~ pi / n, so each negative lobe is crossed by ~6 rings and caught. Near
    a lobe's bottom f ~ f_min + f'' d^2 / 2 with f'' ~ n^2 |lobe depth|, so the grid alone can
    overestimate a minimum by up to ~7 % of the lobe depth (distance <= h / sqrt 2 to the
    nearest point); auto_window removes that error by refining the lowest points locally.
    G: 729 (n = 4), 2 929 (n = 8), 11 733 (n = 16).
    """
    order = check_order(order)
    density = _real(density, "density")
    if not (0.0 < density < math.inf):
        raise ValueError(f"density must be finite and > 0 (got {density!r})")
    rings = max(int(math.ceil(density * order)), 16)
    h = np.pi / rings
    theta = np.arange(rings + 1) * h
    counts = np.maximum(1, np.rint(2.0 * np.pi * np.sin(theta) / h).astype(np.int64))
    counts[0] = counts[-1] = 1
    ring = np.repeat(np.arange(rings + 1), counts)
    first = np.cumsum(counts) - counts
    j = np.arange(counts.sum()) - first[ring]
    phi = (j + 0.5 * (ring % 2)) * (2.0 * np.pi / counts[ring])
    st = np.sin(theta[ring])
    pts = np.stack([st * np.cos(phi), st * np.sin(phi), np.cos(theta[ring])], axis=1)
    pts[0] = (0.0, 0.0, 1.0)
    pts[-1] = (0.0, 0.0, -1.0)
    return pts
