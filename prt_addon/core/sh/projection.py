"""Projection of an equirectangular image into SH by exact per-pixel solid angle.

Blender's equirectangular convention (Cycles and EEVEE), Z up: a direction d = (x, y, z) maps to
u = -atan2(y, x) / (2 pi) + 0.5 and v = atan2(z, hypot(x, y)) / pi + 0.5; v = 0 is the nadir and
is row 0 of `Image.pixels`. The pixel in row j, column k (H rows, W columns) is the patch

    elevation in [(j/H - 1/2) pi, ((j+1)/H - 1/2) pi],   phi in [pi - 2 pi (k+1)/W, pi - 2 pi k/W]

whose exact solid angle is (2 pi / W) (sin e_hi - sin e_lo); the weights telescope to 4 pi.
The image is taken as constant over each pixel, and each basis function is integrated exactly over
each pixel:

    c_i = sum_jk L_jk integral_{pixel jk} y_i dOmega.

So a constant image gives exactly c_0 = sqrt(4 pi) L and 0 elsewhere, for any resolution.
Because y_lm = sqrt(2) Q_l^m(z) sin^m(theta) (cos m phi | sin m phi), the integral is separable:

* over phi, analytically: integral_{phi_k - h}^{phi_k + h} cos(m phi) dphi = (2 sin(m h) / m)
  cos(m phi_k), h = pi / W (and likewise for sin), so each row needs one Fourier sum per m;
* over elevation e (z = sin e, dz = cos e de), integral of Q_l^m(sin e) cos^(m+1)(e) de by
  Gauss-Legendre with enough nodes per row that the smooth integrand is integrated to rounding.

That is O(H W n) for the Fourier part instead of O(H W n^2) for the basis per pixel, accumulated
in float64.

Pixel policy: NaN and +-Inf pixels are set to 0 and negative values are clamped to 0, channel by
channel; every replaced value is counted in the returned PixelReport, never propagated silently.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from .basis import check_order, evaluate, legendre_columns, sh_index

# Rows converted to float64 at a time: bounds the temporary memory to ~ROW_BLOCK * W * 3 * 8 bytes.
ROW_BLOCK = 64


@dataclass
class PixelReport:
    """What the projection had to repair in the input image (counts of channel values)."""

    width: int
    height: int
    nan: int = 0
    inf: int = 0
    negative: int = 0

    @property
    def repaired(self) -> int:
        return self.nan + self.inf + self.negative

    def in_words(self) -> str:
        """The repair as a user reads it: what was wrong with the image and what was done."""

        def values(n):
            return f"{n:,} HDRI value was" if n == 1 else f"{n:,} HDRI values were"

        parts = []
        if self.negative:
            parts.append(f"{values(self.negative)} negative and treated as black")
        if self.nan or self.inf:
            parts.append(f"{values(self.nan + self.inf)} not a number (NaN or infinite) and treated as black")
        return "; ".join(parts)

    def summary(self) -> str:
        if not self.repaired:
            return "all pixels finite and non-negative"
        return f"{self.nan} NaN and {self.inf} infinite values set to 0, {self.negative} negative values clamped to 0"


def row_elevations(height: int) -> tuple[np.ndarray, np.ndarray]:
    """Elevation of each row's centre and edges (row 0 at the bottom), float64."""
    edges = (np.arange(height + 1, dtype=np.float64) / height - 0.5) * np.pi
    centres = ((np.arange(height, dtype=np.float64) + 0.5) / height - 0.5) * np.pi
    return centres, edges


def column_azimuths(width: int) -> np.ndarray:
    """phi = atan2(y, x) at each column's centre: pi at u = 0, 0 at the centre, -pi at u = 1."""
    return np.pi - 2.0 * np.pi * (np.arange(width, dtype=np.float64) + 0.5) / width


def pixel_solid_angles(height: int, width: int) -> np.ndarray:
    """(H,) solid angle of one pixel of each row; W * sum() == 4 pi to rounding."""
    _, edges = row_elevations(height)
    return (2.0 * np.pi / width) * np.diff(np.sin(edges))


def pixel_directions(height: int, width: int) -> np.ndarray:
    """(H, W, 3) unit direction at every pixel centre, rows bottom to top like Image.pixels."""
    elevation, _ = row_elevations(height)
    phi = column_azimuths(width)
    cos_e = np.cos(elevation)[:, None]
    return np.stack(
        np.broadcast_arrays(cos_e * np.cos(phi)[None, :], cos_e * np.sin(phi)[None, :], np.sin(elevation)[:, None]),
        axis=-1,
    )


def as_rgb_image(pixels: npt.ArrayLike) -> np.ndarray:
    """(H, W, C) -> (H, W, 3) view: grey channels are repeated, alpha and extra channels dropped."""
    pixels = np.asarray(pixels)
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    if pixels.ndim != 3 or pixels.shape[0] < 1 or pixels.shape[1] < 1 or pixels.shape[2] < 1:
        raise ValueError(f"pixels must have shape (H, W, C), got {pixels.shape}")
    if pixels.shape[2] < 3:
        return np.repeat(pixels[:, :, :1], 3, axis=2)
    return pixels[:, :, :3]


def sanitize(block: np.ndarray, report: PixelReport) -> np.ndarray:
    """float64 copy of an RGB block with NaN/Inf set to 0 and negatives clamped, counted in report."""
    block = block.astype(np.float64)
    nan = np.isnan(block)
    inf = np.isinf(block)
    report.nan += int(nan.sum())
    report.inf += int(inf.sum())
    block[nan | inf] = 0.0
    negative = block < 0.0
    report.negative += int(negative.sum())
    block[negative] = 0.0
    return block


def row_integration_nodes(height: int, order: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Gauss-Legendre nodes in elevation inside every row: (z, sin_theta, weight), each (H*q,).

    weight includes the Jacobian cos(e) de, so sum(weight * f(z)) = integral of f dz over the row.
    The integrand is a trigonometric polynomial of degree <= order in e over a row of width
    pi / H; q = 4 + ceil(order * pi / H) nodes integrate it to rounding (error ~ (n pi/2H)^2q/(2q)!).
    """
    q = 4 + int(np.ceil(order * np.pi / height))
    nodes, weights = np.polynomial.legendre.leggauss(q)
    _, edges = row_elevations(height)
    half = 0.5 * np.diff(edges)
    mid = 0.5 * (edges[1:] + edges[:-1])
    elevation = (mid[:, None] + half[:, None] * nodes[None, :]).ravel()
    weight = (half[:, None] * weights[None, :]).ravel() * np.cos(elevation)
    return np.sin(elevation), np.cos(elevation), weight, q


def project_equirect(pixels: npt.ArrayLike, order: int) -> tuple[np.ndarray, PixelReport]:
    """Project an (H, W, C) equirectangular image (row 0 = bottom) -> ((order**2, 3), PixelReport)."""
    order = check_order(order)
    rgb = as_rgb_image(pixels)
    height, width, _ = rgb.shape
    report = PixelReport(width=width, height=height)

    m = np.arange(order, dtype=np.float64)
    phi = column_azimuths(width)
    half_width = np.pi / width
    # integral of cos/sin(m phi) over a column = column_integral[m] * value at the column centre.
    column_integral = np.full(order, 2.0 * half_width)
    column_integral[1:] = 2.0 * np.sin(m[1:] * half_width) / m[1:]
    cos_table = np.cos(np.outer(phi, m)) * column_integral  # (W, n)
    sin_table = np.sin(np.outer(phi, m)) * column_integral

    # Row sums of L integral cos(m phi) and L integral sin(m phi): (H, 3, n) each.
    row_cos = np.empty((height, 3, order))
    row_sin = np.empty((height, 3, order))
    for start in range(0, height, ROW_BLOCK):
        block = sanitize(rgb[start : start + ROW_BLOCK], report).transpose(0, 2, 1)
        row_cos[start : start + ROW_BLOCK] = block @ cos_table
        row_sin[start : start + ROW_BLOCK] = block @ sin_table

    z, sin_theta, weight, nodes_per_row = row_integration_nodes(height, order)
    # sqrt(2) sin^m(theta) dz at every node, m = 0 without the sqrt(2).
    node_factor = np.empty((order, len(z)))
    node_factor[0] = weight
    for mm in range(1, order):
        node_factor[mm] = (node_factor[mm - 1] if mm > 1 else weight * np.sqrt(2.0)) * sin_theta

    coeffs = np.empty((order * order, 3))
    for l, mm, q in legendre_columns(z, order):
        row_integral = (q * node_factor[mm]).reshape(height, nodes_per_row).sum(axis=1)
        coeffs[sh_index(l, mm)] = row_integral @ row_cos[:, :, mm]
        if mm > 0:
            coeffs[sh_index(l, -mm)] = row_integral @ row_sin[:, :, mm]
    return coeffs, report


def synthesize_equirect(coeffs: npt.ArrayLike, height: int, width: int) -> np.ndarray:
    """(H, W, C) image of an expansion evaluated at the pixel centres (row 0 = bottom)."""

    coeffs = np.asarray(coeffs, dtype=np.float64)
    dirs = pixel_directions(height, width).reshape(-1, 3)
    values = evaluate(coeffs, dirs)
    return values.reshape(height, width, *coeffs.shape[1:])
