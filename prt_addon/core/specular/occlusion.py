"""Specular occlusion from the baked transfer: a visibility cone against the GGX lobe's cone.

After Jimenez et al. 2016 ("Practical Real-Time Strategies for Accurate Indirect Occlusion",
section 5): visibility is a cone around the bent normal whose cosine-weighted solid angle is the
ambient occlusion, cos theta_v = sqrt(1 - AO) (a cone of half-angle theta about the normal has
AO = sin^2 theta); the reflection lobe is a cone about its direction with
cos theta_s = 2^(-3.32193 alpha^2) (Filament's SpecularAO_Cones). From a diffuse transfer t
(visibility times max(n.l, 0) / pi projected on SH, albedo and bounces excluded) bands 0 and 1
give both: AO = t_0 / y_0 (y_0 = 1 / (2 sqrt(pi)), the open value) and the bent normal is the
direction of the band-1 coefficients (y_{1,-1}, y_{1,0}, y_{1,1}) ~ (y, z, x).

The occlusion is the caps' intersection over the same intersection with the open hemisphere
about the normal: 1 where nothing is hidden, whatever the lobe's tilt, as the split sum already
integrates the lobe over the hemisphere. The intersection of two caps is exact (Mazonka 2012,
"Solid angle of conical surfaces, polyhedral cones, and intersecting spherical caps", eq. 49):

    Omega = 2 (pi - acos((c_g - c_a c_b) / (s_a s_b)) - c_a acos((c_b - c_g c_a) / (s_g s_a))
                  - c_b acos((c_a - c_g c_b) / (s_g s_b)))

for half-angles a, b and axis separation g with |a - b| < g < a + b; the smaller cap when one
holds the other; 0 when they are apart.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

Y0 = 0.5 / np.sqrt(np.pi)
LOBE_EXPONENT = -3.32193  # 2^(-3.32193 alpha^2) = 10^(-alpha^2)
TINY = 1e-9


def cap_solid_angle(cos_a: npt.ArrayLike) -> np.ndarray:
    return 2.0 * np.pi * (1.0 - np.asarray(cos_a, dtype=np.float64))


def cap_intersection(cos_a: npt.ArrayLike, cos_b: npt.ArrayLike, cos_g: npt.ArrayLike) -> np.ndarray:
    """Solid angle shared by two caps of half-angle cosines cos_a, cos_b whose axes make cos_g."""
    ca, cb, cg = np.broadcast_arrays(
        *(np.clip(np.asarray(x, dtype=np.float64), -1.0, 1.0) for x in (cos_a, cos_b, cos_g))
    )
    a, b, g = np.arccos(ca), np.arccos(cb), np.arccos(cg)
    sa, sb, sg = (np.maximum(np.sin(x), TINY) for x in (a, b, g))
    clip = lambda x: np.arccos(np.clip(x, -1.0, 1.0))
    partial = 2.0 * (
        np.pi
        - clip((cg - ca * cb) / (sa * sb))
        - ca * clip((cb - cg * ca) / (sg * sa))
        - cb * clip((ca - cg * cb) / (sg * sb))
    )
    smaller = cap_solid_angle(np.maximum(ca, cb))
    out = np.where(g <= np.abs(a - b), smaller, np.where(g >= a + b, 0.0, partial))
    return np.clip(out, 0.0, smaller)


def visibility_cone(transfer: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(AO, unit bent normal (..., 3), cos theta_v) of transfers (..., >= 4) (bands 0 and 1)."""
    t = np.asarray(transfer, dtype=np.float64)
    ao = np.clip(t[..., 0] / Y0, 0.0, 1.0)
    bent = np.stack([t[..., 3], t[..., 1], t[..., 2]], axis=-1)
    bent = bent / np.maximum(np.linalg.norm(bent, axis=-1, keepdims=True), TINY)
    return ao, bent, np.sqrt(1.0 - ao)


def lobe_cos(alpha: npt.ArrayLike) -> np.ndarray:
    """cos theta_s of the GGX reflection lobe's cone: 2^(-3.32193 alpha^2)."""
    return np.exp2(LOBE_EXPONENT * np.asarray(alpha, dtype=np.float64) ** 2)


def specular_occlusion(
    transfer: npt.ArrayLike, normal: npt.ArrayLike, reflection: npt.ArrayLike, alpha: npt.ArrayLike
) -> np.ndarray:
    """The fraction of the reflection lobe (about unit `reflection`) that the visibility cone
    of `transfer` (in the frame of the unit `normal`) keeps, relative to the open hemisphere."""
    _ao, bent, cos_v = visibility_cone(transfer)
    r = np.asarray(reflection, dtype=np.float64)
    cos_s = lobe_cos(alpha)
    seen = cap_intersection(cos_v, cos_s, np.sum(bent * r, axis=-1))
    open_ = cap_intersection(0.0, cos_s, np.sum(np.asarray(normal, dtype=np.float64) * r, axis=-1))
    return np.where(open_ > TINY, np.clip(seen / np.maximum(open_, TINY), 0.0, 1.0), 1.0)


def lobe_bands(alpha: float, order: int, nodes: int = 512) -> np.ndarray:
    """(order,) k_l = 2 pi int g(c) P_l(c) dc of the lobe g(c) = D(h) max(c, 0) about R (N = V = R,
    c = R.l; core.ibl.sky_prefilter's lobe), by Gauss-Legendre quadrature: by Funk-Hecke,
    int f(l) g(R.l) dl = sum_lm f_lm k_l y_lm(R)."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    a2 = alpha * alpha
    q = a2 + (1.0 - x) * (1.0 - a2) * 0.5
    g = np.maximum(x, 0.0) * a2 / (np.pi * q * q)
    p = np.polynomial.legendre.legvander(x, order - 1)  # (nodes, order): P_l(x)
    return 2.0 * np.pi * (w * g) @ p


def transfer_occlusion(
    transfer: npt.ArrayLike, open_transfer: npt.ArrayLike, basis_at_r: npt.ArrayLike, bands: npt.ArrayLike
) -> np.ndarray:
    """The lobe-weighted visibility from the full transfer: sum_lm k_l t_lm y_lm(R) over the same
    with the open transfer (the clamped cosine about the normal), clamped to [0, 1].
    transfer, open_transfer, basis_at_r: (..., n^2); bands: (n,) lobe_bands."""
    n2 = np.asarray(transfer).shape[-1]
    order = int(round(np.sqrt(n2)))
    k = np.asarray(bands, dtype=np.float64)[np.repeat(np.arange(order), 2 * np.arange(order) + 1)]
    y = np.asarray(basis_at_r, dtype=np.float64) * k
    seen = np.sum(np.asarray(transfer, dtype=np.float64) * y, axis=-1)
    open_ = np.sum(np.asarray(open_transfer, dtype=np.float64) * y, axis=-1)
    return np.where(open_ > TINY, np.clip(seen / np.maximum(open_, TINY), 0.0, 1.0), 1.0)
