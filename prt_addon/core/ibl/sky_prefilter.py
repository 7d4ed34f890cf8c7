"""GGX-prefiltered equirectangular levels of the sky for the viewport's specular (split sum).

Level k of LEVELS holds the radiance prefiltered at roughness k / (LEVELS - 1) (alpha its
square; level 0 the radiance itself), on the same equirect grid as the (reduced) source, Blender's
convention (core.sh.projection: row 0 at the bottom, +X at the centre column). As in
core.ibl.prefilter, N = V = R and each source pixel is weighted by max(n.l, 0) D(h) dOmega,
normalised, with D a function of c = n.l alone: D = alpha^2 / (pi (alpha^2 + (1 - c) (1 - alpha^2) / 2)^2).

Cost: the weights depend only on the output row and the column difference, so each output row
is one circular cross-correlation along the columns, summed over source rows, done with FFTs:
O(H^2 W log W) per level (a 256 x 128 level in about 0.1 s).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..sh import projection, resample

LEVELS = 7
WIDTH = 256  # the levels' width (height WIDTH / 2)


def level_roughness(levels: int = LEVELS) -> np.ndarray:
    return np.linspace(0.0, 1.0, levels)


def ggx_lobe(cosine: np.ndarray, alpha: float) -> np.ndarray:
    """max(n.l, 0) D(h) for N = V = R, as a function of c = n.l."""
    a2 = alpha * alpha
    q = a2 + (1.0 - cosine) * (1.0 - a2) * 0.5
    return np.maximum(cosine, 0.0) * a2 / (np.pi * q * q)


def prefilter_equirect(radiance: np.ndarray, alpha: float) -> np.ndarray:
    """(H, W, C) GGX prefilter of an (H, W, C) equirect image at alpha (> 0)."""
    height, width = radiance.shape[:2]
    directions = projection.pixel_directions(height, width)  # (H, W, 3)
    omega = projection.pixel_solid_angles(height, width)[:, None]  # (H, 1): the same in every column
    spectrum = np.fft.rfft(radiance, axis=1)  # (H, W/2 + 1, C)
    out = np.empty(radiance.shape, dtype=np.float64)
    for i in range(height):
        w = ggx_lobe(directions @ directions[i, 0], alpha) * omega  # output (i, 0) against every source pixel
        # out[i, j] = sum_{r, c} w[r, c - j] L[r, c]: a cross-correlation along the columns.
        corr = np.einsum("rf,rfc->fc", np.conj(np.fft.rfft(w, axis=1)), spectrum)
        out[i] = np.fft.irfft(corr, n=width, axis=0) / w.sum()
    return out


def sky_levels(pixels: npt.ArrayLike, width: int = WIDTH, levels: int = LEVELS) -> np.ndarray:
    """(levels, width / 2, width, 3) float64: the image reduced to width x width / 2 (exact area
    means, repaired as the projection repairs it), then prefiltered at each level's roughness."""
    rgb = np.asarray(pixels)
    if rgb.ndim != 3 or rgb.shape[0] < 1:
        raise ValueError(f"an equirect image must be (H, W, C), got {rgb.shape}")
    if width < 4 or width % 2:
        raise ValueError(f"the levels' width must be even and at least 4, got {width}")
    h, w = rgb.shape[:2]
    reduced, _report, _energy = resample.reduce_equirect(rgb, min(h, width // 2), min(w, width))
    if reduced.shape[:2] != (width // 2, width):  # a smaller image: nearest-pixel upscale
        rows = (np.arange(width // 2) * reduced.shape[0]) // (width // 2)
        cols = (np.arange(width) * reduced.shape[1]) // width
        reduced = reduced[rows][:, cols]
    out = np.empty((levels, width // 2, width, 3))
    for k, r in enumerate(level_roughness(levels)):
        out[k] = reduced if r == 0.0 else prefilter_equirect(reduced, float(r * r))
    return out


def constant_levels(colour: npt.ArrayLike, width: int = WIDTH, levels: int = LEVELS) -> np.ndarray:
    """The levels of a constant sky: the colour everywhere."""
    c = np.clip(np.asarray(colour, dtype=np.float64)[:3], 0.0, None)
    return np.broadcast_to(c, (levels, width // 2, width, 3)).copy()


def wrapped_columns(levels: npt.ArrayLike) -> np.ndarray:
    """(levels, H, W + 2, C): each level with its last column copied before its first and its first
    after its last, so that a clamp-to-edge bilinear lookup at x = (1 + u W) / (W + 2) wraps
    around in longitude as the equirect image does."""
    a = np.asarray(levels)
    return np.concatenate([a[:, :, -1:], a, a[:, :, :1]], axis=2)
