"""An image's mean over UV triangles (a bounce's albedo per triangle): bilinear lookups at sub-triangle centroids."""

import numpy as np
import numpy.typing as npt


def bilinear_repeat(image: npt.ArrayLike, uv: npt.ArrayLike, dtype: npt.DTypeLike = np.float64) -> np.ndarray:
    """(N, C) bilinear lookup of image (H, W, C), row 0 at v = 0, at uv (N, 2), wrapping at the
    edges (Blender's Image Texture, Linear and Repeat: texel centres at (i + 0.5) / size), in
    `dtype` (float32 for many lookups of an 8- or 16-bit image: its rounding is far below a step)."""
    img = np.asarray(image)
    height, width = img.shape[:2]
    flat = img.reshape(height * width, -1)
    uv = np.asarray(uv, dtype=dtype).reshape(-1, 2)
    x = uv[:, 0] * uv.dtype.type(width) - uv.dtype.type(0.5)
    y = uv[:, 1] * uv.dtype.type(height) - uv.dtype.type(0.5)
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    c0, r0 = x0.astype(np.int64) % width, y0.astype(np.int64) % height
    c1, r1 = (c0 + 1) % width, (r0 + 1) % height

    def at(r, c):
        return flat[r * width + c].astype(dtype, copy=False)

    low = at(r0, c0) * (1 - fx) + at(r0, c1) * fx
    high = at(r1, c0) * (1 - fx) + at(r1, c1) * fx
    return low * (1 - fy) + high * fy


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
