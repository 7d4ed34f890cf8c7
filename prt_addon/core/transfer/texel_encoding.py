"""Texel transfer as 8-bit image planes: each coefficient quantised to 8 or 16 bits over its range, split into bytes.

For a (res, res, C) image of coefficients, per channel c over every texel (gutter included):
offset_c = min, scale_c = max - min, and q = round((t - offset) / scale x (256^P - 1)) for P
planes (1: 8 bits, 2: 16 bits); plane p holds byte P - 1 - p of q (plane 0 the high byte). A
reader decodes t = offset + scale x q / (256^P - 1) (a channel of scale 0 is its offset).
docs/export.md, "Texel transfer", is the format; the planes go into 8-bit RGBA PNGs.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

PLANES = {"unorm16_png": 2, "unorm8_png": 1}  # encoding name -> bytes per value


def levels(planes: int) -> int:
    return 256**planes - 1


def encode(image: npt.ArrayLike, planes: int) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """([P uint8 arrays of image's shape], offset (C,), scale (C,)) of float values (..., C)."""
    values = np.asarray(image, dtype=np.float64)
    flat = values.reshape(-1, values.shape[-1])
    lo, hi = flat.min(axis=0), flat.max(axis=0)
    scale = hi - lo
    safe = np.where(scale > 0, scale, 1.0)
    top = levels(planes)
    q = np.rint(np.clip((values - lo) / safe, 0.0, 1.0) * top).astype(np.uint32)
    out = [((q >> (8 * (planes - 1 - p))) & 255).astype(np.uint8) for p in range(planes)]
    return out, lo, np.where(scale > 0, scale, 0.0)


def decode(planes: list[npt.ArrayLike], offset: npt.ArrayLike, scale: npt.ArrayLike) -> np.ndarray:
    """float64 values of the planes (the reader's rule)."""
    q = np.zeros(np.shape(planes[0]), dtype=np.float64)
    for plane in planes:
        q = q * 256.0 + np.asarray(plane, dtype=np.float64)
    return np.asarray(offset) + np.asarray(scale) * q / levels(len(planes))
