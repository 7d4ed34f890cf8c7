"""An image looked up at UV points as Blender's Image Texture node samples it: its interpolation and extension."""

import numpy as np
import numpy.typing as npt

# The Image Texture node's Interpolation and Extension as the display's albedo_mode numbers them.
LINEAR, CLOSEST = 0, 1
REPEAT, EXTEND, CLIP, MIRROR = 0, 1, 2, 3


def _texel_index(i: np.ndarray, n: int, extension: int) -> tuple[np.ndarray, np.ndarray | None]:
    """(index in 0..n-1, None or the mask of texels outside the image) of integer texel
    coordinates i, by Blender's Image Texture extension (REPEAT, EXTEND, CLIP, MIRROR above)."""
    if extension == EXTEND:
        return np.clip(i, 0, n - 1), None
    if extension == CLIP:
        return np.clip(i, 0, n - 1), (i < 0) | (i >= n)
    if extension == MIRROR:
        m = np.mod(i, 2 * n)
        return np.minimum(m, 2 * n - 1 - m), None
    return np.mod(i, n), None


def sample_image(
    image: npt.ArrayLike,
    uv: npt.ArrayLike,
    dtype: npt.DTypeLike = np.float64,
    interpolation: int = LINEAR,
    extension: int = REPEAT,
) -> np.ndarray:
    """(N, C) lookup of image (H, W, C), row 0 at v = 0, at uv (N, 2), as Blender's Image Texture
    samples it: Linear (bilinear, texel centres at (i + 0.5) / size) or Closest, and Repeat,
    Extend, Clip (black outside) or Mirror; in `dtype` (float32 for many lookups of an 8- or
    16-bit image: its rounding is far below a step)."""
    img = np.asarray(image)
    height, width = img.shape[:2]
    flat = img.reshape(height * width, -1)
    uv = np.asarray(uv, dtype=dtype).reshape(-1, 2)
    scalar = uv.dtype.type

    def at(x, y):
        (c, c_out), (r, r_out) = _texel_index(x, width, extension), _texel_index(y, height, extension)
        values = flat[r * width + c].astype(dtype, copy=False)
        if c_out is not None:
            values = np.where((c_out | r_out)[:, None], scalar(0.0), values)
        return values

    if interpolation == CLOSEST:
        return at(
            np.floor(uv[:, 0] * scalar(width)).astype(np.int64), np.floor(uv[:, 1] * scalar(height)).astype(np.int64)
        )
    x = uv[:, 0] * scalar(width) - scalar(0.5)
    y = uv[:, 1] * scalar(height) - scalar(0.5)
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    c0, r0 = x0.astype(np.int64), y0.astype(np.int64)
    low = at(c0, r0) * (1 - fx) + at(c0 + 1, r0) * fx
    high = at(c0, r0 + 1) * (1 - fx) + at(c0 + 1, r0 + 1) * fx
    return low * (1 - fy) + high * fy
