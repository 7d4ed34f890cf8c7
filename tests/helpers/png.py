"""A PNG decoder in numpy and zlib, for the images the core writes."""

import struct
import zlib

import numpy as np


def _decode_png(data):
    """(H, W, 4) of an 8-bit RGBA PNG with filters 0-2 (the test's own reader)."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, header = 8, b"", None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos : pos + 8])
        body = data[pos + 8 : pos + 8 + length]
        assert struct.unpack(">I", data[pos + 8 + length : pos + 12 + length])[0] == zlib.crc32(kind + body)
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    width, height, depth, colour = header[:4]
    assert (depth, colour) == (8, 6)
    raw = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(height, width * 4 + 1)
    rows = np.zeros((height, width * 4), np.uint8)
    for j in range(height):
        kind, line = raw[j, 0], raw[j, 1:]
        prev = rows[j - 1] if j else np.zeros_like(line)
        if kind == 0:
            rows[j] = line
        elif kind == 2:
            rows[j] = line + prev
        else:
            raise AssertionError(f"filter {kind}")
    return rows.reshape(height, width, 4)
