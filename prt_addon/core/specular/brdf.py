"""The GGX split-sum BRDF table (Karis 2013) and its multiple-scattering compensation.

Conventions (Blender's Principled BSDF): alpha = roughness^2; D is GGX; the shadowing is
Smith's height-correlated G2 = 1 / (1 + Lambda(mu_v) + Lambda(mu_l)); the Fresnel term is
Schlick's F = F0 + (1 - F0) (1 - v.h)^5. The directional albedo of the single-scattering lobe is
then F0 A + B with

    A = int (1 - Fc) f1 mu_l dl,  B = int Fc f1 mu_l dl,  Fc = (1 - v.h)^5,  f1 = D G2 / (4 mu_v mu_l)

(the split sum's second factor), tabulated over (mu_v, roughness) at texel centres: entry
[j, i] holds mu_v = (i + 0.5) / N and roughness (j + 0.5) / N. The integral is a deterministic
GGX importance sum over Hammersley points (Karis 2013), estimator G2 (v.h) / (mu_v n.h).

Multiple scattering (Fdez-Aguera 2019, "A Multiple-Scattering Microfacet Model for Real-Time
Image-based Lighting", eq. 14-16): E_ss = A + B, E_ms = 1 - E_ss, F_avg = F0 + (1 - F0) / 21,
F_ms = (F0 A + B) F_avg / (1 - E_ms F_avg); the lobe's total albedo is F0 A + B + F_ms E_ms.
A white conductor (F0 = 1) reflects everything: 1 exactly. For analytic lights the single
lobe is scaled by 1 + F0 (1 / E_ss - 1) (Turquin 2019, "Practical multiple scattering
compensation for microfacet models", eq. 17).

A dielectric of index `ior` has F0 = ((ior - 1) / (ior + 1))^2 times 2 x Specular IOR Level
(Principled: level 0.5 keeps the IOR's F0). Principled layers the diffuse under it with the
albedo the specular leaves: a white dielectric in a white furnace reflects 1 as well.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

TABLE_SIZE = 32
SAMPLES = 16384  # 2048 left 0.8 % at mu_v = 0.1
MIN_ALPHA = 1e-3  # GGX at alpha 0 is a delta: the table's first rows stay finite
MIN_MU = 1e-4


def alpha_of(roughness: npt.ArrayLike) -> np.ndarray:
    """GGX alpha of a Principled roughness: roughness^2, at least MIN_ALPHA."""
    r = np.clip(np.asarray(roughness, dtype=np.float64), 0.0, 1.0)
    return np.maximum(r * r, MIN_ALPHA)


def smith_lambda(mu: npt.ArrayLike, alpha: npt.ArrayLike) -> np.ndarray:
    """Smith's Lambda of GGX: (-1 + sqrt(1 + alpha^2 tan^2 theta)) / 2."""
    mu = np.clip(np.asarray(mu, dtype=np.float64), MIN_MU, 1.0)
    a2 = np.asarray(alpha, dtype=np.float64) ** 2
    return 0.5 * (np.sqrt(1.0 + a2 * (1.0 / (mu * mu) - 1.0)) - 1.0)


def ggx_d(mu_h: npt.ArrayLike, alpha: npt.ArrayLike) -> np.ndarray:
    """GGX normal distribution D(h) = alpha^2 / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2)."""
    mu_h = np.asarray(mu_h, dtype=np.float64)
    a2 = np.asarray(alpha, dtype=np.float64) ** 2
    q = mu_h * mu_h * (a2 - 1.0) + 1.0
    return a2 / (np.pi * q * q)


def g2(mu_v: npt.ArrayLike, mu_l: npt.ArrayLike, alpha: npt.ArrayLike) -> np.ndarray:
    """Smith's height-correlated masking-shadowing G2."""
    return 1.0 / (1.0 + smith_lambda(mu_v, alpha) + smith_lambda(mu_l, alpha))


def hammersley(count: int) -> np.ndarray:
    """(count, 2) Hammersley points: ((i + 0.5) / count, the base-2 radical inverse of i)."""
    i = np.arange(count, dtype=np.int64)
    inverse = np.zeros(count)
    rest, scale = i.copy(), 0.5
    while rest.any():
        inverse += scale * (rest & 1)
        rest >>= 1
        scale *= 0.5
    return np.stack([(i + 0.5) / count, inverse], axis=1)


def split_sum(mu_v: npt.ArrayLike, alpha: npt.ArrayLike, samples: int = SAMPLES) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of the split sum at each (mu_v, alpha) (broadcast together)."""
    mu_v, alpha = np.broadcast_arrays(
        np.clip(np.asarray(mu_v, dtype=np.float64), MIN_MU, 1.0), np.asarray(alpha, dtype=np.float64)
    )
    u = hammersley(samples)
    a2 = alpha[..., None] ** 2
    cos_h = np.sqrt((1.0 - u[:, 0]) / (1.0 + (a2 - 1.0) * u[:, 0]))  # GGX-distributed half vectors
    sin_h = np.sqrt(np.maximum(1.0 - cos_h * cos_h, 0.0))
    phi = 2.0 * np.pi * u[:, 1]
    mv = mu_v[..., None]
    # v = (sin_v, 0, mu_v); h = (sin_h cos phi, sin_h sin phi, cos_h); l = 2 (v.h) h - v
    v_h = np.sqrt(np.maximum(1.0 - mv * mv, 0.0)) * sin_h * np.cos(phi) + mv * cos_h
    mu_l = 2.0 * v_h * cos_h - mv
    keep = (mu_l > 0.0) & (v_h > 0.0)
    weight = np.where(keep, g2(mv, np.where(keep, mu_l, 1.0), alpha[..., None]) * v_h / (mv * cos_h), 0.0)
    fc = np.clip(1.0 - v_h, 0.0, 1.0) ** 5
    return ((1.0 - fc) * weight).mean(axis=-1), (fc * weight).mean(axis=-1)


def table_coordinates(size: int = TABLE_SIZE) -> np.ndarray:
    """(size,) the table's texel centres, (i + 0.5) / size, for mu_v and roughness alike."""
    return (np.arange(size) + 0.5) / size


def brdf_table(size: int = TABLE_SIZE, samples: int = SAMPLES) -> np.ndarray:
    """(size, size, 2) float64 (A, B): row j roughness (j + 0.5) / size, column i mu_v (i + 0.5) / size."""
    c = table_coordinates(size)
    out = np.empty((size, size, 2))
    for j, rough in enumerate(c):  # a row at a time: (size, samples) temporaries
        out[j, :, 0], out[j, :, 1] = split_sum(c, alpha_of(rough), samples)
    return out


def dielectric_f0(ior: npt.ArrayLike, level: npt.ArrayLike = 0.5) -> np.ndarray:
    """F0 of Principled's dielectric layer: ((ior - 1) / (ior + 1))^2 x 2 level, in [0, 1]."""
    ior = np.maximum(np.asarray(ior, dtype=np.float64), 1.0)
    return np.clip(((ior - 1.0) / (ior + 1.0)) ** 2 * 2.0 * np.asarray(level, dtype=np.float64), 0.0, 1.0)


def specular_albedo(f0: npt.ArrayLike, a: npt.ArrayLike, b: npt.ArrayLike) -> np.ndarray:
    """Directional albedo of the GGX lobe with multiple scattering (Fdez-Aguera 2019)."""
    f0 = np.asarray(f0, dtype=np.float64)
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    single = f0 * a + b
    e_ms = 1.0 - (a + b)
    f_avg = f0 + (1.0 - f0) / 21.0
    f_ms = single * f_avg / (1.0 - e_ms * f_avg)
    return single + f_ms * e_ms


def energy_compensation(f0: npt.ArrayLike, a: npt.ArrayLike, b: npt.ArrayLike) -> np.ndarray:
    """Factor on the single-scattering lobe for analytic lights: 1 + F0 (1 / E_ss - 1) (Turquin 2019)."""
    e_ss = np.maximum(np.asarray(a, dtype=np.float64) + np.asarray(b, dtype=np.float64), 1e-4)
    return 1.0 + np.asarray(f0, dtype=np.float64) * (1.0 / e_ss - 1.0)


def principled_weights(
    base: npt.ArrayLike, metallic: npt.ArrayLike, f0_dielectric: npt.ArrayLike, a: npt.ArrayLike, b: npt.ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """(specular albedo, diffuse weight) of a Principled surface under environment light:
    metallic mixes a conductor of F0 = base with a dielectric whose diffuse (base colour times
    the PRT diffuse) gets the albedo its specular leaves, 1 - E_spec."""
    m = np.asarray(metallic, dtype=np.float64)
    metal = specular_albedo(base, a, b)
    dielectric = specular_albedo(f0_dielectric, a, b)
    return m * metal + (1.0 - m) * dielectric, (1.0 - m) * (1.0 - dielectric)
