"""Post-processing of a baked (res, res, C) lightmap: bilinear lookup, gutter dilation and UV seams.

Conventions (those of core.transfer.texels and of the viewer): row 0 is v in [0, 1 / res), texel
(row, col) has its centre at ((col + 0.5) / res, (row + 0.5) / res), and lookups are bilinear with
clamp-to-edge, as a GPU samples a texture with LINEAR filtering and CLAMP_TO_EDGE. docs/texels.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

NEIGHBOURS = [(dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if dy or dx]
GUTTER = 4  # texels filled around each chart by default (dilate's passes)
SEAM_WEIGHT = 10.0  # weight of the seam term against the data term of a covered texel
GUTTER_WEIGHT = 0.3  # data weight of an uncovered (gutter) texel: freer to meet the seam
SAMPLES_PER_TEXEL = 2  # seam samples per texel of edge length (the longer side)
SMOOTH_TOLERANCE = 1e-3  # corner normals (unit) within this in every component: a smooth edge
CG_ITERATIONS = 100
CG_TOLERANCE = 1e-6  # relative residual of every channel (float32 images hold ~1e-7)


def bilinear_taps(uv: npt.ArrayLike, height: int, width: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(N, 4) flat texel indices (row * width + col) and (N, 4) weights of bilinear lookups at uv
    (N, 2), clamp-to-edge, texel centres at (i + 0.5) / size."""
    width = height if width is None else width
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    x = uv[:, 0] * width - 0.5
    y = uv[:, 1] * height - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = x - x0, y - y0
    cols = np.clip(np.stack([x0, x0 + 1], 1), 0, width - 1).astype(np.int64)
    rows = np.clip(np.stack([y0, y0 + 1], 1), 0, height - 1).astype(np.int64)
    index = (rows[:, [0, 0, 1, 1]] * width) + cols[:, [0, 1, 0, 1]]
    weight = np.stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy], axis=1)
    return index, weight


def bilinear(image: npt.ArrayLike, uv: npt.ArrayLike) -> np.ndarray:
    """(N, C) bilinear lookup of image (H, W, C) (or (H, W)) at uv (N, 2), clamp-to-edge."""
    img = np.asarray(image)
    height, width = img.shape[:2]
    flat = img.reshape(height * width, -1)
    index, weight = bilinear_taps(uv, height, width)
    return np.einsum("nk,nkc->nc", weight, flat[index].astype(np.float64))


def dilate(image: npt.ArrayLike, covered: npt.ArrayLike, passes: int = GUTTER, rest: str = "nearest") -> np.ndarray:
    """image (H, W, C) with its uncovered texels filled: each of `passes` passes gives every
    unfilled texel with a filled 8-neighbour the mean of its filled 8-neighbours (a gutter of
    `passes` texels: every texel within Chebyshev distance `passes` of a covered one). The texels
    further out get the value of the nearest filled texel (rest="nearest") or 0 (rest="zero").

    The gutter goes ring by ring (work proportional to the texels filled); "nearest" is the exact
    Euclidean nearest filled texel (between texel centres) of _nearest_seed."""
    if rest not in ("nearest", "zero"):
        raise ValueError("rest must be 'nearest' or 'zero'")
    img = np.asarray(image)
    squeeze = img.ndim == 2
    height, width = img.shape[:2]
    img3 = img.reshape(height, width, -1)
    cov = np.asarray(covered, dtype=bool).reshape(height, width)
    # A padded grid: the border ring is never filled nor open, so no bounds checks.
    # (In the image's precision, float32 at least: a 2048 x 2048 order-8 map is 1 GiB a copy.)
    grid = np.zeros((height + 2, width + 2, img3.shape[2]), dtype=np.result_type(img3.dtype, np.float32))
    inner = grid[1:-1, 1:-1]
    inner[...] = img3
    inner[~cov] = 0.0
    filled2 = np.zeros((height + 2, width + 2), dtype=bool)
    filled2[1:-1, 1:-1] = cov
    open2 = np.zeros_like(filled2)
    open2[1:-1, 1:-1] = ~cov
    near_open = np.zeros_like(filled2)
    for dy, dx in NEIGHBOURS:
        near_open[1:-1, 1:-1] |= open2[1 + dy : height + 1 + dy, 1 + dx : width + 1 + dx]
    values, filled, open_ = grid.reshape(-1, img3.shape[2]), filled2.ravel(), open2.ravel()
    wide = width + 2
    offsets = np.array([dy * wide + dx for dy, dx in NEIGHBOURS])
    front = np.flatnonzero(filled2 & near_open)  # the covered texels next to an open one
    layer = 0
    while len(front) and layer < passes:
        ring = front[:, None] + offsets
        ring = np.unique(ring[open_[ring]])
        if not len(ring):
            break
        neighbours = ring[:, None] + offsets  # (K, 8)
        known = filled[neighbours]
        total = np.einsum("kn,knc->kc", known.astype(np.float64), values[neighbours])
        values[ring] = total / known.sum(axis=1)[:, None]
        filled[ring] = True
        open_[ring] = False
        front = ring
        layer += 1
    out = grid[1:-1, 1:-1].copy()
    done = filled2[1:-1, 1:-1].ravel()
    if rest == "nearest" and done.any() and not done.all():
        nearest = _nearest_seed(done.reshape(height, width)).ravel()
        gap = np.flatnonzero(~done)
        flat = out.reshape(-1, img3.shape[2])
        flat[gap] = flat[nearest[gap]]
    return out[:, :, 0] if squeeze else out


def _nearest_seed(seeds: np.ndarray) -> np.ndarray:
    """(H, W) flat index (row * W + col) of the nearest True texel of `seeds` (H, W) (Euclidean
    distance between texel centres; any True texel required), by the exact separable distance
    transform of Felzenszwalb and Huttenlocher (2012, "Distance transforms of sampled functions"):
    the nearest seed of each column by running extrema, then per row the lower envelope of the
    parabolas (q - c)^2 + g(c)^2, every row at once (the loops run over the columns)."""
    height, width = seeds.shape
    rows = np.arange(height)[:, None]
    above = np.maximum.accumulate(np.where(seeds, rows, -1), axis=0)  # nearest seed row <= r
    below = np.minimum.accumulate(np.where(seeds, rows, 2 * height)[::-1], axis=0)[::-1]  # >= r
    take_above = (above >= 0) & ((rows - above) <= (below - rows))
    nearest_row = np.where(take_above, above, below)  # 2 * height: no seed in the column
    big = 4.0 * (height + width) ** 2  # stands for +inf and never wins against a real seed
    f = np.where(nearest_row < height, (nearest_row - rows).astype(np.float64) ** 2, big)
    # Flat tables indexed by row start + column: a take on a flat array costs a fraction of 2-D
    # fancy indexing, which each column step paid several times.
    fv = (f + (np.arange(width) ** 2)[None, :]).ravel()  # f(c) + c^2, the parabola of column c
    base, zw = np.arange(height) * width, width + 1
    zbase = np.arange(height) * zw
    v = np.zeros(height * width, dtype=np.int64)  # the envelope's parabolas (columns), per row
    z = np.full(height * zw, np.inf)  # and the boundaries between them
    z[zbase] = -np.inf
    k = np.zeros(height, dtype=np.int64)
    for q in range(1, width):
        fq = fv[base + q]
        while True:
            vk = v[base + k]
            s = (fq - fv[base + vk]) / (2.0 * (q - vk))
            pop = s <= z[zbase + k]
            if not pop.any():
                break
            k -= pop
        k += 1
        v[base + k] = q
        z[zbase + k] = s
        z[zbase + k + 1] = np.inf
    # Parabola j of a row serves the columns q with z[j] <= q < z[j + 1] (z[1 .. k + 1]
    # increasing), so its index is the count of boundaries below q: one searchsorted over the
    # rows laid end to end, each clipped to [-1, width] and lifted by row * (width + 2). A
    # boundary is a fraction with denominator at most 2 width, never within rounding of q.
    bounds = np.clip(z.reshape(height, zw)[:, 1:], -1.0, float(width))
    bounds[np.arange(width)[None, :] > k[:, None]] = width  # (beyond each row's envelope)
    lift = (np.arange(height) * (width + 2))[:, None]
    where = np.searchsorted((bounds + lift).ravel(), (np.arange(width)[None, :] + lift).ravel())
    best = v[where.reshape(height, width)]  # (each row's search starts at row * width: v's row)
    return nearest_row[np.arange(height)[:, None], best] * width + best


@dataclass
class SeamPairs:
    """Edges equal in 3D (the same two mesh vertices) but cut in UV: for each, its two triangles
    and the UVs of its ends on either side (uv_a[:, 0] and uv_b[:, 0] at vertices[:, 0])."""

    vertices: np.ndarray  # (E, 2) int64 mesh vertices, the lower first
    triangles: np.ndarray  # (E, 2) int64, side a then side b
    uv_a: np.ndarray  # (E, 2, 2) float64
    uv_b: np.ndarray  # (E, 2, 2) float64

    def __len__(self) -> int:
        return len(self.vertices)

    def samples(self, resolution: int, per_texel: float = SAMPLES_PER_TEXEL) -> tuple[np.ndarray, ...]:
        """Points along every seam at the same parameters on both sides: (uv on side a (N, 2),
        uv on side b (N, 2), seam of each (N,)), ceil(per_texel x the longer side's length in
        texels) points per seam (at least one), at the middles of equal parts."""
        length = np.maximum(
            np.linalg.norm(self.uv_a[:, 1] - self.uv_a[:, 0], axis=1),
            np.linalg.norm(self.uv_b[:, 1] - self.uv_b[:, 0], axis=1),
        )
        count = np.maximum(1, np.ceil(per_texel * resolution * length)).astype(np.int64)
        seam = np.repeat(np.arange(len(count)), count)
        t = (np.arange(len(seam)) - np.repeat(np.cumsum(count) - count, count) + 0.5) / count[seam]
        t = t[:, None]
        a = self.uv_a[seam, 0] + t * (self.uv_a[seam, 1] - self.uv_a[seam, 0])
        b = self.uv_b[seam, 0] + t * (self.uv_b[seam, 1] - self.uv_b[seam, 0])
        return a, b, seam


def seam_pairs(
    corner_vertices: npt.ArrayLike,
    uvs: npt.ArrayLike,
    tolerance: float = 1e-6,
    normals: npt.ArrayLike | None = None,
    normal_tolerance: float = SMOOTH_TOLERANCE,
) -> SeamPairs:
    """The UV seams of a mesh: corner_vertices (T, 3) mesh vertex per triangle corner, uvs (T, 3, 2).
    An edge (vertex pair) of two triangles whose ends' UVs differ by more than `tolerance` (in any
    component) between the two is a seam; an edge of more than two triangles pairs them in
    order of triangle (first with second, second with third, ...); boundary edges are no seams.
    With corner `normals` (T, 3, 3), only smooth edges are seams (the two triangles' normals at
    both ends within `normal_tolerance`): across a hard edge the light is not continuous."""
    cv = np.asarray(corner_vertices, dtype=np.int64).reshape(-1, 3)
    uv = np.asarray(uvs, dtype=np.float64).reshape(-1, 3, 2)
    if len(cv) != len(uv):
        raise ValueError("corner_vertices and uvs must have one row per triangle")
    a, b = cv, cv[:, [1, 2, 0]]
    ua, ub = uv, uv[:, [1, 2, 0]]
    nrm = np.zeros((len(cv), 3, 3)) if normals is None else np.asarray(normals, dtype=np.float64).reshape(-1, 3, 3)
    na, nb = nrm.reshape(-1, 3), nrm[:, [1, 2, 0]].reshape(-1, 3)
    swap = (a > b).ravel()
    lo, hi = np.minimum(a, b).ravel(), np.maximum(a, b).ravel()
    ua, ub = ua.reshape(-1, 2), ub.reshape(-1, 2)
    uv_lo = np.where(swap[:, None], ub, ua)
    uv_hi = np.where(swap[:, None], ua, ub)
    n_lo, n_hi = np.where(swap[:, None], nb, na), np.where(swap[:, None], na, nb)
    tri = np.repeat(np.arange(len(cv)), 3)
    keep = lo != hi
    order = np.lexsort((tri[keep], hi[keep], lo[keep]))
    idx = np.flatnonzero(keep)[order]
    lo, hi, tri, uv_lo, uv_hi = lo[idx], hi[idx], tri[idx], uv_lo[idx], uv_hi[idx]
    n_lo, n_hi = n_lo[idx], n_hi[idx]
    i = np.flatnonzero((lo[1:] == lo[:-1]) & (hi[1:] == hi[:-1]) & (tri[1:] != tri[:-1]))
    j = i + 1
    gap = np.maximum(np.abs(uv_lo[i] - uv_lo[j]).max(axis=1), np.abs(uv_hi[i] - uv_hi[j]).max(axis=1))
    bend = np.maximum(np.abs(n_lo[i] - n_lo[j]).max(axis=1), np.abs(n_hi[i] - n_hi[j]).max(axis=1))
    s = (gap > tolerance) & (bend <= normal_tolerance)
    i, j = i[s], j[s]
    return SeamPairs(
        np.stack([lo[i], hi[i]], axis=1),
        np.stack([tri[i], tri[j]], axis=1),
        np.stack([uv_lo[i], uv_hi[i]], axis=1),
        np.stack([uv_lo[j], uv_hi[j]], axis=1),
    )


def fix_seams(
    image: npt.ArrayLike,
    seams: SeamPairs,
    covered: npt.ArrayLike,
    weight: float = SEAM_WEIGHT,
    gutter_weight: float = GUTTER_WEIGHT,
    iterations: int = CG_ITERATIONS,
    tolerance: float = CG_TOLERANCE,
) -> np.ndarray:
    """image (H, W, C) with its texels along the seams changed to minimise (Iwanicki 2013, "Lighting
    Technology of The Last of Us"; the ands/seamoptimizer library)

        E(x) = weight sum_k |bilinear_a(x, k) - bilinear_b(x, k)|^2 + sum_i d_i |x_i - x0_i|^2

    over the texels the seam samples' bilinear taps touch (d_i = 1 if covered, gutter_weight if
    not); the others are unchanged. The normal equations (D + weight B^T B) x = D x0, B the (N, n)
    differences of the two sides' tap weights, are solved by Jacobi-preconditioned conjugate
    gradients, all C channels at once, from x0, until every channel's residual is below
    `tolerance` of its right-hand side or for at most `iterations` steps."""
    img = np.asarray(image)
    squeeze = img.ndim == 2
    height, width = img.shape[:2]
    flat = img.reshape(height * width, -1)
    out = np.array(flat, dtype=np.result_type(flat.dtype, np.float32))
    if len(seams) == 0:
        return out.reshape(img.shape)
    uv_a, uv_b, _seam = seams.samples(max(height, width))
    ia, wa = bilinear_taps(uv_a, height, width)
    ib, wb = bilinear_taps(uv_b, height, width)
    texels, local = np.unique(np.concatenate([ia, ib], axis=1), return_inverse=True)
    local = local.reshape(len(ia), 8)
    coef = np.concatenate([wa, -wb], axis=1)
    n, channels = len(texels), flat.shape[1]
    x0 = np.ascontiguousarray(flat[texels].T, dtype=np.float64)  # (C, n): channel-major
    d = np.where(np.asarray(covered, dtype=bool).reshape(-1)[texels], 1.0, float(gutter_weight))
    # Every channel at once: channel c's texel i is entry c n + i of the raveled (C, n) array.
    taps = local[None] + n * np.arange(channels)[:, None, None]  # (C, N, 8)
    taps_flat = taps.ravel()

    def apply(x):
        diff = np.einsum("nk,cnk->cn", coef, np.take(x, taps))  # bilinear_a - bilinear_b
        grad = np.bincount(taps_flat, weights=(coef[None] * diff[:, :, None]).ravel(), minlength=channels * n)
        return d * x + weight * grad.reshape(channels, n)

    diag = d + weight * np.bincount(local.ravel(), weights=(coef * coef).ravel(), minlength=n)
    rhs = d * x0
    x = x0.copy()
    r = rhs - apply(x)
    limit = float(tolerance) * np.maximum(np.linalg.norm(rhs, axis=1), 1e-300)
    z = r / diag
    p = z.copy()
    rz = np.einsum("cn,cn->c", r, z)
    for _ in range(int(iterations)):
        if (np.linalg.norm(r, axis=1) <= limit).all():
            break
        ap = apply(p)
        pap = np.einsum("cn,cn->c", p, ap)
        alpha = np.divide(rz, pap, out=np.zeros_like(rz), where=pap > 0)
        x += alpha[:, None] * p
        r -= alpha[:, None] * ap
        z = r / diag
        rz_new = np.einsum("cn,cn->c", r, z)
        beta = np.divide(rz_new, rz, out=np.zeros_like(rz), where=rz > 0)
        p = z + beta[:, None] * p
        rz = rz_new
    out[texels] = x.T
    return out.reshape(img.shape[:2]) if squeeze else out.reshape(img.shape)
