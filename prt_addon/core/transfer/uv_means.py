"""An image's mean over UV triangles (a bounce's albedo per triangle): bilinear lookups at sub-triangle centroids."""

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


def bilinear_repeat(image: npt.ArrayLike, uv: npt.ArrayLike, dtype: npt.DTypeLike = np.float64) -> np.ndarray:
    """sample_image with Blender's Image Texture defaults, Linear and Repeat."""
    return sample_image(image, uv, dtype)


def centroid_barycentrics(n: int) -> np.ndarray:
    """(n * n, 3) barycentrics of the centroids of a triangle's n x n equal sub-triangles: a
    midpoint rule, each point of weight 1 / n^2."""
    points = []
    for i in range(n):
        for j in range(n - i):
            points.append(((i + 1 / 3) / n, (j + 1 / 3) / n))
            if i + j <= n - 2:
                points.append(((i + 2 / 3) / n, (j + 2 / 3) / n))
    ab = np.array(points)
    return np.c_[ab, 1.0 - ab.sum(axis=1)]


def triangle_means(image: npt.ArrayLike, uv_triangles: npt.ArrayLike, n: int = 4, block: int = 1 << 16) -> np.ndarray:
    """(T, C) mean of image over each UV triangle of uv_triangles (T, 3, 2): the midpoint rule on
    n x n sub-triangles, bilinear with repeat."""
    tri = np.asarray(uv_triangles, dtype=np.float64).reshape(-1, 3, 2)
    bary = centroid_barycentrics(n)
    img = np.asarray(image)
    out = np.empty((len(tri), img.shape[2] if img.ndim == 3 else 1))
    for a in range(0, len(tri), block):
        part = tri[a : a + block]
        uv = np.einsum("kj,tjc->tkc", bary, part).reshape(-1, 2)
        out[a : a + block] = bilinear_repeat(img, uv).reshape(len(part), len(bary), -1).mean(axis=1)
    return out
