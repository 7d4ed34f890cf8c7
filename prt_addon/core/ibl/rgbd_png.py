"""RGBD encoding of HDR radiance into 8-bit RGBA, and a PNG writer (numpy, zlib and struct only).

RGBD as Babylon.js packs and unpacks it (its toRGBD / fromRGBD shader functions, with the
gamma-2.2 approximation its decoding pass uses):

    D = clamp(floor(max(255 / max(r, g, b), 1)) / 255, 0, 1)      (alpha, stored linearly)
    rgb = clamp((colour D)^(1 / 2.2), 0, 1)                       (colour channels)
    decoded = rgb^2.2 / D

so values up to 1 keep D = 1 (plain gamma-encoded 8 bit) and brighter ones divide by D, up to a
largest encodable value of 255 (brighter texels are clipped to it).
"""

from __future__ import annotations

import struct
import zlib

import numpy as np
import numpy.typing as npt

GAMMA = 2.2
MAX_VALUE = 255.0  # the brightest value RGBD can hold


def rgbd_encode(rgb: npt.ArrayLike) -> np.ndarray:
    """(..., 3) linear radiance -> (..., 4) uint8 RGBD; negative and non-finite values become 0."""
    c = np.asarray(rgb, dtype=np.float64)
    c = np.where(np.isfinite(c), np.maximum(c, 0.0), 0.0)
    peak = np.maximum(c.max(axis=-1), 1e-7)
    d = np.clip(np.floor(np.maximum(MAX_VALUE / peak, 1.0)) / 255.0, 0.0, 1.0)
    encoded = np.clip(c * d[..., None], 0.0, 1.0) ** (1.0 / GAMMA)
    out = np.empty((*c.shape[:-1], 4), dtype=np.uint8)
    out[..., :3] = np.rint(encoded * 255.0)
    out[..., 3] = np.rint(d * 255.0)
    return out


def rgbd_decode(rgbd: npt.ArrayLike) -> np.ndarray:
    """(..., 4) uint8 RGBD -> (..., 3) linear float64, as Babylon decodes it."""
    v = np.asarray(rgbd, dtype=np.float64) / 255.0
    return v[..., :3] ** GAMMA / v[..., 3:4]


def _chunk(kind: bytes, payload: bytes) -> bytes:
    return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", zlib.crc32(kind + payload))


def png_bytes(rgba: npt.ArrayLike, level: int = 6) -> bytes:
    """A PNG file (8-bit RGBA, colour type 6, no colour-space chunk) of (H, W, 4) uint8, row 0
    the top of the picture. Every row but the first uses the Up filter (type 2)."""
    pixels = np.ascontiguousarray(rgba, dtype=np.uint8)
    if pixels.ndim != 3 or pixels.shape[2] != 4 or pixels.shape[0] < 1 or pixels.shape[1] < 1:
        raise ValueError(f"expected an (H, W, 4) image, got shape {pixels.shape}")
    height, width = pixels.shape[:2]
    rows = pixels.reshape(height, width * 4)
    filtered = np.empty((height, width * 4 + 1), dtype=np.uint8)
    filtered[:, 0] = 2
    filtered[0, 0] = 0
    filtered[0, 1:] = rows[0]
    filtered[1:, 1:] = rows[1:] - rows[:-1]  # uint8 arithmetic wraps modulo 256, as PNG wants
    header = struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)
    return b"".join(
        [
            b"\x89PNG\r\n\x1a\n",
            _chunk(b"IHDR", header),
            _chunk(b"IDAT", zlib.compress(filtered.tobytes(), level)),
            _chunk(b"IEND", b""),
        ]
    )
