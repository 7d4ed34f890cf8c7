"""Integral-preserving reduction of equirectangular images, with pixel repair and L2 energy.

An equirect pixel is the patch (elevation band) x (azimuth band) of projection.py; its solid angle
is (2 pi / W) (sin e_hi - sin e_lo). The reduced image's pixel value is the solid-angle-weighted
mean of the source over its patch (the exact overlap of the source patches, fractions included), so

    integral of the reduced image over any of its pixels == integral of the source over it,

and in particular the reduced image has the same total flux and the same c_0 for any size.
Higher coefficients change by the variation of each basis function inside one reduced pixel:
`needed_height` chooses the size from the order (see docs/world.md for the measured error).

The source is read ROW_BLOCK rows at a time, so apart from the caller's input the memory is
O(ROW_BLOCK * W + H_out * W_out) floats. NaN and +-Inf values are set to 0 and negative values
clamped to 0 before averaging (counted in a projection.PixelReport, as project_equirect does),
so one bad pixel cannot poison a reduced pixel.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from .analytic import clamped_cosine_zonal
from .basis import convolve_zonal, order_of
from .projection import PixelReport, as_rgb_image, row_elevations, sanitize

ROW_BLOCK = 64
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec.709 / scene-linear luminance weights


def needed_height(order: int) -> int:
    """Rows an order-n projection needs: at least 256, and 16 per band (measured in docs/world.md).

    A reduced pixel moves a sun by up to half its size, so the error depends on the pixel size far
    more than on the order: 256 rows kept every coefficient of the bundled HDRIs within 0.5 %.
    """
    return max(256, 16 * int(order))


def target_size(height: int, width: int, order: int) -> tuple[int, int]:
    """(H_out, W_out): at most needed_height(order) rows and 4 times as many columns, never more
    than the source; the aspect ratio is kept when rows are reduced."""
    need = needed_height(order)
    h_out = min(height, need)
    w_out = max(1, int(round(width * h_out / height)))
    return h_out, min(w_out, width, 4 * need)


def _interval_overlaps(src_edges, dst_edges):
    """Dense (n_dst, n_src) matrix of overlap lengths of [src_k, src_k+1] with [dst_j, dst_j+1]."""
    lo = np.maximum(dst_edges[:-1, None], src_edges[None, :-1])
    hi = np.minimum(dst_edges[1:, None], src_edges[None, 1:])
    return np.clip(hi - lo, 0.0, None)


def reduce_columns(block: np.ndarray, width_out: int) -> np.ndarray:
    """Average (b, W, C) over W_out equal azimuth intervals (fractional overlaps included).

    Every column spans the same azimuth, so the exact mean over an interval [a, b] (in columns)
    is (S(b) - S(a)) / (b - a) with S the piecewise-linear integral of the prefix sums.
    """
    width = block.shape[1]
    if width % width_out == 0:
        return block.reshape(block.shape[0], width_out, width // width_out, -1).mean(axis=2)
    prefix = np.zeros((block.shape[0], width + 1, block.shape[2]))
    np.cumsum(block, axis=1, out=prefix[:, 1:])
    edges = np.arange(width_out + 1, dtype=np.float64) * (width / width_out)
    whole = np.minimum(np.floor(edges).astype(np.int64), width - 1)
    frac = (edges - whole)[None, :, None]
    integral = prefix[:, whole] + frac * block[:, whole]
    return np.diff(integral, axis=1) / (width / width_out)


def row_matrix(height: int, height_out: int) -> np.ndarray:
    """(H_out, H) weights: overlap of the rows in z = sin(elevation), i.e. in solid angle."""
    _, src_e = row_elevations(height)
    _, dst_e = row_elevations(height_out)
    src, dst = np.sin(src_e), np.sin(dst_e)
    src[0], src[-1], dst[0], dst[-1] = -1.0, 1.0, -1.0, 1.0
    a = _interval_overlaps(src, dst)
    return a / a.sum(axis=1, keepdims=True)


def reduce_equirect(pixels: npt.ArrayLike, height_out: int, width_out: int) -> tuple[np.ndarray, PixelReport, float]:
    """Reduce an (H, W, C) equirect image (row 0 at the bottom) to (H_out, W_out, 3) float64.

    Returns (reduced, report, energy): report counts the repaired source values, energy is the
    L2 energy integral of luminance(L)^2 dOmega of the repaired *source* (before reduction), so
    that the truncation of an SH projection can be measured against the full-resolution image.
    A reduction to the same size only repairs (and converts to float64).
    """
    rgb = as_rgb_image(pixels)
    height, width, _ = rgb.shape
    if not (1 <= height_out <= height and 1 <= width_out <= width):
        raise ValueError(f"cannot reduce {width}x{height} to {width_out}x{height_out}")
    report = PixelReport(width=width, height=height)
    same_columns = width_out == width
    rows = row_matrix(height, height_out)  # (H_out, H)
    solid = (2.0 * np.pi / width) * np.diff(np.sin(row_elevations(height)[1]))
    out = np.zeros((height_out, width_out, 3))
    energy = 0.0
    for start in range(0, height, ROW_BLOCK):
        stop = min(start + ROW_BLOCK, height)
        block = sanitize(rgb[start:stop], report)  # (b, W, 3)
        lum = block @ LUMINANCE
        energy += float(solid[start:stop] @ np.einsum("ij,ij->i", lum, lum))
        if not same_columns:
            block = reduce_columns(block, width_out)
        out += np.tensordot(rows[:, start:stop], block, axes=(1, 0))
    return out, report, energy


def image_energy(rgb: np.ndarray) -> float:
    """L2 energy integral of luminance^2 dOmega of a repaired (H, W, 3) equirect image."""
    height, width, _ = rgb.shape
    solid = (2.0 * np.pi / width) * np.diff(np.sin(row_elevations(height)[1]))
    lum = np.asarray(rgb, dtype=np.float64) @ LUMINANCE
    return float(solid @ np.einsum("ij,ij->i", lum, lum))


def truncation_fraction(coeffs: npt.ArrayLike, energy: float) -> float:
    """Fraction of the L2 luminance energy not captured by the coefficients (Parseval), in [0, 1]."""
    if energy <= 0.0:
        return 0.0
    lum = np.asarray(coeffs, dtype=np.float64) @ LUMINANCE
    return float(np.clip(1.0 - float(lum @ lum) / energy, 0.0, 1.0))


# Bands beyond 32 hold < 1e-6 of the energy of any diffuse (clamped-cosine) convolution: its
# kernel's zonal coefficients fall as l^-5/2, so their squares as l^-5.
DIFFUSE_REFERENCE_ORDER = 32


def diffuse_truncation_fraction(reference_coeffs: np.ndarray, order: int) -> float:
    """Fraction of the L2 luminance energy of the diffuse shading E/pi (the lighting convolved with
    max(0, cos)/pi, Funk-Hecke) that lies beyond `order`, from coefficients of a higher order."""

    reference_order = order_of(len(reference_coeffs))
    diffuse = convolve_zonal(reference_coeffs, clamped_cosine_zonal(reference_order)) @ LUMINANCE
    total = float(diffuse @ diffuse)
    if total <= 0.0:
        return 0.0
    kept = float(diffuse[: order * order] @ diffuse[: order * order])
    return float(np.clip(1.0 - kept / total, 0.0, 1.0))
