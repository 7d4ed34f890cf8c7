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
SEAM_WEIGHT = 10.0  # weight of the seam term against the data term of a covered texel
GUTTER_WEIGHT = 0.1  # data weight of an uncovered (gutter) texel: it is free to meet the seam
SAMPLES_PER_TEXEL = 2  # seam samples per texel of edge length (the longer side)
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


def _shifted(a, dy, dx, fill):
    """a shifted so that out[i, j] = a[i + dy, j + dx] (fill outside)."""
    out = np.full_like(a, fill)
    h, w = a.shape[:2]
    out[max(0, -dy) : h - max(0, dy), max(0, -dx) : w - max(0, dx)] = a[
        max(0, dy) : h - max(0, -dy), max(0, dx) : w - max(0, -dx)
    ]
    return out


def dilate(image: npt.ArrayLike, covered: npt.ArrayLike, passes: int = 4, rest: str = "nearest") -> np.ndarray:
    """image (H, W, C) with its uncovered texels filled: each of `passes` passes gives every
    unfilled texel with a filled 8-neighbour the mean of its filled 8-neighbours (a gutter of
    `passes` texels: every texel within Chebyshev distance `passes` of a covered one). The texels
    further out get the value of the nearest filled texel (rest="nearest", Euclidean distance
    between texel centres, by jump flooding) or 0 (rest="zero")."""
    img = np.array(image, dtype=np.float64)
    squeeze = img.ndim == 2
    if squeeze:
        img = img[:, :, None]
    filled = np.array(covered, dtype=bool).reshape(img.shape[:2])
    img[~filled] = 0.0
    for _ in range(int(passes)):
        if filled.all():
            break
        total = np.zeros_like(img)
        count = np.zeros(filled.shape)
        for dy, dx in NEIGHBOURS:
            total += _shifted(img, dy, dx, 0.0)  # unfilled texels hold 0
            count += _shifted(filled, dy, dx, False)
        grow = ~filled & (count > 0)
        img[grow] = total[grow] / count[grow, None]
        filled |= grow
    if rest == "nearest" and filled.any() and not filled.all():
        sy, sx = _nearest_seeds(filled)
        gap = ~filled
        img[gap] = img[sy[gap], sx[gap]]
    elif rest not in ("nearest", "zero"):
        raise ValueError("rest must be 'nearest' or 'zero'")
    return img[:, :, 0] if squeeze else img


def _nearest_seeds(seeds):
    """(row, col) of the nearest True texel of every texel, by jump flooding (Rong and Tan 2006)
    with a final step of 1 (JFA+1), which leaves almost no texel with a wrong seed."""
    h, w = seeds.shape
    rows, cols = np.indices((h, w))
    sy = np.where(seeds, rows, -1)
    sx = np.where(seeds, cols, -1)
    big = np.int64(4 * (h + w) ** 2)
    dist = np.where(seeds, 0, big)
    step = 1 << max(0, int(np.ceil(np.log2(max(h, w)))) - 1)
    steps = []
    while step >= 1:
        steps.append(step)
        step //= 2
    for step in steps + [1]:
        for dy in (-step, 0, step):
            for dx in (-step, 0, step):
                if not (dy or dx):
                    continue
                cy, cx = _shifted(sy, dy, dx, -1), _shifted(sx, dy, dx, -1)
                d = np.where(cy >= 0, (cy - rows) ** 2 + (cx - cols) ** 2, big)
                better = d < dist
                sy, sx, dist = np.where(better, cy, sy), np.where(better, cx, sx), np.where(better, d, dist)
    return sy, sx


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


def seam_pairs(corner_vertices: npt.ArrayLike, uvs: npt.ArrayLike, tolerance: float = 1e-6) -> SeamPairs:
    """The UV seams of a mesh: corner_vertices (T, 3) mesh vertex per triangle corner, uvs (T, 3, 2).
    An edge (vertex pair) of two triangles whose ends' UVs differ by more than `tolerance` (in any
    component) between the two is a seam; an edge of more than two triangles pairs them in
    order of triangle (first with second, second with third, ...); boundary edges are no seams."""
    cv = np.asarray(corner_vertices, dtype=np.int64).reshape(-1, 3)
    uv = np.asarray(uvs, dtype=np.float64).reshape(-1, 3, 2)
    if len(cv) != len(uv):
        raise ValueError("corner_vertices and uvs must have one row per triangle")
    a, b = cv, cv[:, [1, 2, 0]]
    ua, ub = uv, uv[:, [1, 2, 0]]
    swap = (a > b).ravel()
    lo, hi = np.minimum(a, b).ravel(), np.maximum(a, b).ravel()
    ua, ub = ua.reshape(-1, 2), ub.reshape(-1, 2)
    uv_lo = np.where(swap[:, None], ub, ua)
    uv_hi = np.where(swap[:, None], ua, ub)
    tri = np.repeat(np.arange(len(cv)), 3)
    keep = lo != hi
    order = np.lexsort((tri[keep], hi[keep], lo[keep]))
    idx = np.flatnonzero(keep)[order]
    lo, hi, tri, uv_lo, uv_hi = lo[idx], hi[idx], tri[idx], uv_lo[idx], uv_hi[idx]
    i = np.flatnonzero((lo[1:] == lo[:-1]) & (hi[1:] == hi[:-1]) & (tri[1:] != tri[:-1]))
    j = i + 1
    gap = np.maximum(np.abs(uv_lo[i] - uv_lo[j]).max(axis=1), np.abs(uv_hi[i] - uv_hi[j]).max(axis=1))
    s = gap > tolerance
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
