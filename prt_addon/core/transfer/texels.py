"""Lightmap texels as bake points: conservative rasterisation of UV triangles, S samples per texel.

Texel (row, col) of a square map of R texels per side is the square [col, col + 1] x [row, row + 1]
in texel coordinates (X, Y) = R (u, v); row 0 is v in [0, 1 / R) (Blender's Image.pixels). A texel
is covered when a triangle overlaps its square with positive area; its S samples sit at
(col, row) + offsets[s]. A sample a triangle of the texel contains keeps its place (the first such
triangle in triangle order owns it); one that none contains is snapped to the closest point of the
nearest triangle overlapping the texel. With an inset d, every sample is then moved into its
triangle shrunk about its (3D) incentre, so that it lies at least min(d, INSET_FRACTION r) from the
triangle's edges in position space (r: the inradius). docs/texels.md.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

# Rotated-grid 2x2 supersampling (RGSS): one sample in each row and column of a 4x4 grid, mean
# at the texel centre; the average over them approximates the texel's footprint average.
SAMPLE_OFFSETS = np.array([[0.375, 0.125], [0.875, 0.375], [0.625, 0.875], [0.125, 0.625]])

INSET_FRACTION = 1.0 / 3.0  # the inset is at most this fraction of the triangle's inradius
INSIDE_EPS = 1e-9  # barycentric tolerance of "contains" (on an edge counts as inside)
STRICT_EPS = 1e-7  # "strictly inside" for overlap counting: every barycentric above this
SNAP_EPS = 1e-9  # span ends within this many texels of an integer are that integer
DEGENERATE = 1e-12  # |2 x UV area| <= DEGENERATE x (longest UV edge)^2: zero UV area
BAND_PAIRS = 1 << 15  # (triangle, texel) pairs resolved at a time


@dataclass
class TexelSamples:
    """The covered texels of a map and S surface samples in each (see the module docstring)."""

    resolution: int
    texels: np.ndarray  # (P,) int64 row * resolution + col, sorted
    triangles: np.ndarray  # (S, P) int64
    barycentrics: np.ndarray  # (S, P, 3) float64, >= 0, summing to 1
    positions: np.ndarray  # (S, P, 3) float64
    normals: np.ndarray  # (S, P, 3) float64 unit
    overlapping: int
    outside: int
    degenerate: int

    @property
    def count(self) -> int:
        return len(self.texels)

    def covered(self) -> np.ndarray:
        """(res, res) bool, True at the covered texels."""
        mask = np.zeros(self.resolution * self.resolution, dtype=bool)
        mask[self.texels] = True
        return mask.reshape(self.resolution, self.resolution)

    def average(self, values: npt.ArrayLike) -> np.ndarray:
        """(P, C) texel values, the mean over its S samples of values (S P, C) given in the order
        of positions.reshape(-1, 3) (sample-major: all texels' sample 0, then sample 1, ...)."""
        v = np.asarray(values, dtype=np.float64)
        return v.reshape(len(self.triangles), self.count, -1).mean(axis=0)

    def image(self, values: npt.ArrayLike, fill: float = 0.0) -> np.ndarray:
        """(res, res, C) float image with values (P, C) (or (P,)) at the covered texels."""
        v = np.asarray(values)
        v = v.reshape(len(v), -1)
        out = np.full((self.resolution * self.resolution, v.shape[1]), fill, dtype=np.result_type(v, np.float32))
        out[self.texels] = v
        return out.reshape(self.resolution, self.resolution, -1)


def _spans(x, y, valid, resolution):
    """(triangle, row, first col, last col) of every row band each valid triangle overlaps."""
    ymin, ymax = y.min(axis=1), y.max(axis=1)
    r0 = np.maximum(np.floor(ymin + SNAP_EPS), 0)
    r1 = np.minimum(np.ceil(ymax - SNAP_EPS) - 1, resolution - 1)
    rows = np.where(valid, r1 - r0 + 1, 0).clip(0).astype(np.int64)
    tri = np.repeat(np.arange(len(x)), rows)
    row = np.repeat(r0.astype(np.int64), rows) + np.arange(len(tri)) - np.repeat(np.cumsum(rows) - rows, rows)
    # The x-extent of (triangle intersected with the band y in [lo, hi]): each edge clipped to the band.
    lo = np.maximum(row, ymin[tri])
    hi = np.minimum(row + 1.0, ymax[tri])
    xmin = np.full(len(tri), np.inf)
    xmax = np.full(len(tri), -np.inf)
    for j in range(3):
        px, py, qx, qy = x[tri, j], y[tri, j], x[tri, (j + 1) % 3], y[tri, (j + 1) % 3]
        dy = qy - py
        flat = dy == 0
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = (lo - py) / dy, (hi - py) / dy
        t0 = np.where(flat, 0.0, np.maximum(np.minimum(ta, tb), 0.0))
        t1 = np.where(flat, 1.0, np.minimum(np.maximum(ta, tb), 1.0))
        hit = np.where(flat, (py >= lo) & (py <= hi), t0 <= t1)
        xa, xb = px + t0 * (qx - px), px + t1 * (qx - px)
        xmin = np.where(hit, np.minimum(xmin, np.minimum(xa, xb)), xmin)
        xmax = np.where(hit, np.maximum(xmax, np.maximum(xa, xb)), xmax)
    c0 = np.maximum(np.floor(xmin + SNAP_EPS), 0).astype(np.int64)
    c1 = np.minimum(np.ceil(xmax - SNAP_EPS) - 1, resolution - 1).astype(np.int64)
    keep = c1 >= c0
    return tri[keep], row[keep], c0[keep], c1[keep]


def _closest_on_edges(px, py, vx, vy):
    """Closest point on the boundary of triangles (vx, vy: (M, 3)) to points (px, py: (M,)):
    (squared distance, barycentrics (M, 3))."""
    best = np.full(len(px), np.inf)
    bary = np.zeros((len(px), 3))
    for j in range(3):
        k = (j + 1) % 3
        dx, dy = vx[:, k] - vx[:, j], vy[:, k] - vy[:, j]
        t = ((px - vx[:, j]) * dx + (py - vy[:, j]) * dy) / (dx * dx + dy * dy)
        np.clip(t, 0.0, 1.0, out=t)
        ex, ey = vx[:, j] + t * dx - px, vy[:, j] + t * dy - py
        d2 = ex * ex + ey * ey
        better = d2 < best
        best = np.where(better, d2, best)
        row = np.zeros((len(px), 3))
        row[:, j], row[:, k] = 1.0 - t, t
        bary[better] = row[better]
    return best, bary


def texel_samples(
    uvs: npt.ArrayLike,
    positions: npt.ArrayLike,
    normals: npt.ArrayLike,
    resolution: int,
    offsets: npt.ArrayLike = SAMPLE_OFFSETS,
    inset: float = 0.0,
    inset_fraction: float = INSET_FRACTION,
    threads: int = 1,
) -> TexelSamples:
    """uvs (T, 3, 2), positions (T, 3, 3), normals (T, 3, 3) per triangle corner (smooth where the
    mesh is smooth: the caller passes corner normals). See the module docstring. threads > 1
    resolves bands of rows on that many threads (no gain was measured on the 2-core test machine
    under load: the work is bound by memory)."""
    res = int(resolution)
    if res < 1:
        raise ValueError("resolution must be at least 1")
    uv = np.asarray(uvs, dtype=np.float64).reshape(-1, 3, 2)
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3, 3)
    nrm = np.asarray(normals, dtype=np.float64).reshape(-1, 3, 3)
    if not len(uv) == len(pos) == len(nrm):
        raise ValueError("uvs, positions and normals must have one row per triangle")
    off = np.asarray(offsets, dtype=np.float64).reshape(-1, 2)
    count_t = len(uv)
    x, y = uv[:, :, 0] * res, uv[:, :, 1] * res
    finite = np.isfinite(uv).all(axis=(1, 2))
    outside = int((finite & ((uv < 0) | (uv > 1)).any(axis=(1, 2))).sum())
    e1x, e1y, e2x, e2y = x[:, 1] - x[:, 0], y[:, 1] - y[:, 0], x[:, 2] - x[:, 0], y[:, 2] - y[:, 0]
    cross: np.ndarray = e1x * e2y - e1y * e2x
    longest = np.max([e1x**2 + e1y**2, e2x**2 + e2y**2, (e2x - e1x) ** 2 + (e2y - e1y) ** 2], axis=0)
    with np.errstate(invalid="ignore"):
        valid = finite & (np.abs(cross) > DEGENERATE * longest)
    degenerate = int(count_t - valid.sum())
    safe = np.where(valid, cross, 1.0)
    # b1, b2 = inverse([e1 e2]) (p - x0); b0 = 1 - b1 - b2.
    inv = np.stack([e2y, -e2x, -e1y, e1x], axis=1) / safe[:, None]

    # Inset: b_j >= m_j = d / h_j (h_j the 3D altitude from corner j) is the triangle shrunk about
    # its incentre (barycentrics L_j / perimeter) by k = 1 - d / r, r = |2 x area| / perimeter.
    edge_len = np.linalg.norm(pos[:, [2, 0, 1]] - pos[:, [1, 2, 0]], axis=2)  # opposite corner j
    perimeter = edge_len.sum(axis=1)
    twice_area = np.linalg.norm(np.cross(pos[:, 1] - pos[:, 0], pos[:, 2] - pos[:, 0]), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inradius = np.where(perimeter > 0, twice_area / perimeter, 0.0)
        incentre = np.where(perimeter[:, None] > 0, edge_len / perimeter[:, None], 1.0 / 3.0)
        depth = np.minimum(max(float(inset), 0.0), inset_fraction * inradius)
        shrink = np.where(inradius > 0, depth / inradius, 0.0)  # 1 - k
    floor = shrink[:, None] * incentre  # m_j
    ix, iy = (incentre * x).sum(axis=1), (incentre * y).sum(axis=1)
    sx = ix[:, None] + (1 - shrink[:, None]) * (x - ix[:, None])
    sy = iy[:, None] + (1 - shrink[:, None]) * (y - iy[:, None])
    face = np.cross(pos[:, 1] - pos[:, 0], pos[:, 2] - pos[:, 0])
    face *= np.where(np.einsum("ij,ij->i", face, nrm.sum(axis=1)) < 0, -1.0, 1.0)[:, None]

    tri, row, c0, c1 = _spans(x, y, valid, res)
    # Exact count of covered texels: the union of each row's column intervals (rows kept apart by
    # an offset of res + 1 so that one running maximum serves them all).
    start = row * (res + 1) + c0
    order = np.argsort(start, kind="stable")
    tri, row, c0, c1, start = tri[order], row[order], c0[order], c1[order], start[order]
    end = row * (res + 1) + c1 + 1
    before = np.concatenate([[-1], np.maximum.accumulate(end)[:-1]]) if len(end) else end
    new_texels = np.maximum(end - np.maximum(start, before), 0)
    covered_total = int(new_texels.sum())

    count_s = len(off)
    out = TexelSamples(
        res,
        np.empty(covered_total, dtype=np.int64),
        np.empty((count_s, covered_total), dtype=np.int64),
        np.empty((count_s, covered_total, 3)),
        np.empty((count_s, covered_total, 3)),
        np.empty((count_s, covered_total, 3)),
        0,
        outside,
        degenerate,
    )
    pos9, nrm9 = pos.reshape(-1, 9), nrm.reshape(-1, 9)
    tables = _Tables(x, y, inv, floor, shrink, sx, sy, pos9, nrm9, face, off, bool((floor > 0).any()))
    width = c1 - c0 + 1
    done_pairs = np.cumsum(width)
    bounds = np.searchsorted(done_pairs, np.arange(BAND_PAIRS, int(done_pairs[-1]) if len(width) else 0, BAND_PAIRS))
    # Cut only between rows, so that no texel is split across bands.
    cuts = np.unique(np.concatenate([[0], np.searchsorted(row, row[np.minimum(bounds, len(row) - 1)]), [len(row)]]))
    # Each band's first texel: the texels new in the spans before it.
    first_texel = np.concatenate([[0], np.cumsum(new_texels)])

    def band(a, b):
        w = width[a:b]
        first = np.repeat(np.cumsum(w) - w, w)
        col = np.repeat(c0[a:b], w) + np.arange(len(first)) - first
        key = np.sort((np.repeat(row[a:b], w) * res + col) * count_t + np.repeat(tri[a:b], w))
        return _resolve_band(key, count_t, res, tables, out, int(first_texel[a]))

    pairs = list(zip(cuts[:-1], cuts[1:]))
    if threads > 1 and len(pairs) > 1:  # numpy releases the GIL; bands write disjoint slices
        with ThreadPoolExecutor(max_workers=int(threads)) as pool:
            results = list(pool.map(lambda ab: band(*ab), pairs))
    else:
        results = [band(a, b) for a, b in pairs]
    out.overlapping = sum(r[1] for r in results)
    assert all(r[0] == first_texel[b] for r, (_a, b) in zip(results, pairs))
    return out


@dataclass
class _Tables:
    """Per-triangle tables of texel_samples (texel coordinates)."""

    x: np.ndarray  # (T, 3) corner X = R u
    y: np.ndarray  # (T, 3) corner Y = R v
    inv: np.ndarray  # (T, 4) b1, b2 = inv (p - corner 0)
    floor: np.ndarray  # (T, 3) the inset's lowest barycentrics m_j
    shrink: np.ndarray  # (T,) 1 - k
    sx: np.ndarray  # (T, 3) the shrunk triangle
    sy: np.ndarray
    pos9: np.ndarray  # (T, 9) corner positions
    nrm9: np.ndarray  # (T, 9) corner normals
    face: np.ndarray  # (T, 3) face normals, on the corner normals' side
    off: np.ndarray  # (S, 2) sample offsets
    inset: bool  # any floor above 0


def _resolve_band(key, count_t, res, tb, out, filled):
    """The samples of the texels of one band of rows, from its sorted (texel, triangle) keys,
    written into `out` from texel `filled` on; returns (the end of its texels, its overlapping
    texels)."""
    pair_texel = key // count_t
    pair_tri = key - pair_texel * count_t
    n = len(key)
    new = np.ones(n, dtype=bool)
    new[1:] = pair_texel[1:] != pair_texel[:-1]
    starts = np.flatnonzero(new)
    g = len(starts)
    count_s = len(tb.off)
    pr, pc = np.divmod(pair_texel, res)
    px = pc[None, :] + tb.off[:, 0, None]  # (S, n)
    py = pr[None, :] + tb.off[:, 1, None]
    dx, dy = px - tb.x[pair_tri, 0], py - tb.y[pair_tri, 0]
    i4 = tb.inv[pair_tri].T
    b1 = i4[0] * dx + i4[1] * dy
    b2 = i4[2] * dx + i4[3] * dy
    b0 = 1.0 - b1 - b2
    winner = np.broadcast_to(starts, (count_s, g)).copy()
    overlapping = 0
    if g < n:
        # Texels shared by several triangles: the first containing a sample owns it, else the
        # nearest (in UV) gets it snapped.
        size = np.diff(np.append(starts, n))
        shared = np.flatnonzero(size > 1)
        pairs = np.flatnonzero(np.repeat(size > 1, size))
        sub_starts = np.searchsorted(pairs, starts[shared])
        sub_group = np.repeat(np.arange(len(shared)), size[shared])
        sub_low = np.minimum(np.minimum(b0[:, pairs], b1[:, pairs]), b2[:, pairs])
        inside = sub_low >= -INSIDE_EPS
        any_in = np.logical_or.reduceat(inside, sub_starts, axis=1)
        score = np.where(inside, -1.0, np.inf)
        si, pi = np.nonzero(~any_in[:, sub_group])
        t = pair_tri[pairs[pi]]
        score[si, pi] = _closest_on_edges(px[si, pairs[pi]], py[si, pairs[pi]], tb.x[t], tb.y[t])[0]
        best = np.minimum.reduceat(score, sub_starts, axis=1)
        index = np.where(score == best[:, sub_group], pairs[None, :], n)
        winner[:, shared] = np.minimum.reduceat(index, sub_starts, axis=1)
        strict = (sub_low > STRICT_EPS).astype(np.int32)
        overlapping = int((np.add.reduceat(strict, sub_starts, axis=1) >= 2).any(axis=0).sum())
    sl = slice(filled, filled + g)
    bary = np.empty((count_s, g, 3))  # contiguous (einsum is ~3x slower into strided views)
    if g == n:
        bary[..., 0], bary[..., 1], bary[..., 2] = b0, b1, b2
    else:
        for j, b in enumerate((b0, b1, b2)):
            bary[..., j] = np.take_along_axis(b, winner, axis=1)
    wt = pair_tri[winner]  # (S, G)
    if tb.inset:
        floor = tb.floor[wt]
        fs, fi = np.nonzero((bary < floor).any(axis=-1))
    else:
        fs, fi = np.nonzero(bary.min(axis=-1) < 0)
    if len(fs):
        t = wt[fs, fi]
        w = winner[fs, fi]
        _d, edge = _closest_on_edges(px[fs, w], py[fs, w], tb.sx[t], tb.sy[t])
        fixed = (1.0 - tb.shrink[t, None]) * edge + tb.floor[t]
        np.clip(fixed, 0.0, 1.0, out=fixed)
        bary[fs, fi] = fixed / fixed.sum(axis=1, keepdims=True)
    out.texels[sl] = pair_texel[starts]
    out.triangles[:, sl] = wt
    out.barycentrics[:, sl] = bary
    out.positions[:, sl] = np.einsum("sgj,sgjk->sgk", bary, np.take(tb.pos9, wt, axis=0).reshape(count_s, g, 3, 3))
    nn = np.einsum("sgj,sgjk->sgk", bary, np.take(tb.nrm9, wt, axis=0).reshape(count_s, g, 3, 3))
    length = np.sqrt(np.einsum("sgi,sgi->sg", nn, nn))
    flat = ~(length > 1e-12)
    if flat.any():  # opposite corner normals cancel: the face normal
        nn[flat] = tb.face[wt[flat]]
        length[flat] = np.sqrt(np.einsum("ki,ki->k", nn[flat], nn[flat]))
    nn /= np.where(length > 0, length, 1.0)[..., None]
    out.normals[:, sl] = nn
    return filled + g, overlapping
