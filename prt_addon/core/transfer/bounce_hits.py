"""The shadow pass's hits as transport entries: the hit sink, its barycentrics and node choice.

t^b(h) is interpolated over the hit triangle's nodes (the bake points of the mesh it belongs to):
each hit keeps one node, the corner j chosen with probability equal to its barycentric weight,
so the entry is an unbiased estimate of the linear interpolation with one matrix entry per hit
(core.transfer.bounce). The choice is a hash of (point, direction), so a bake does not depend on threads
or slicing. A hit on a triangle's back face (the ray travels along its normal) reflects nothing.

Memory: one entry per front-face hit, 4 + 4 C bytes while the shadow pass runs (node int32, C =
1 or 3 float32 weights, the hit surface's albedo per colour channel times 4 / N max(0, n . w);
the rows as runs, one per point and block).
"""

from __future__ import annotations

import functools
import threading

import numpy as np
import numpy.typing as npt

from .hit_albedo import HitAlbedo


def _hash_unit(rows: np.ndarray, kdir: np.ndarray, seed: int, work: _Work | None = None) -> np.ndarray:
    """Uniform [0, 1] float32 per (row, direction): murmur3's 32-bit finaliser of a mix (in
    `work`'s buffers when given: valid until its next use)."""
    m = len(rows)
    h = np.empty(m, np.uint32) if work is None else work.get("hash", m, np.uint32)
    k = np.empty(m, np.uint32) if work is None else work.get("hash_k", m, np.uint32)
    np.copyto(h, rows, casting="unsafe")  # (as astype(np.uint32): the low 32 bits)
    np.copyto(k, kdir, casting="unsafe")
    with np.errstate(over="ignore"):
        h *= np.uint32(0x9E3779B1)
        k *= np.uint32(0x85EBCA77)
        k += np.uint32(seed & 0xFFFFFFFF)
        h ^= k
        np.right_shift(h, np.uint32(16), out=k)
        h ^= k
        h *= np.uint32(0x85EBCA6B)
        np.right_shift(h, np.uint32(13), out=k)
        h ^= k
        h *= np.uint32(0xC2B2AE35)
        np.right_shift(h, np.uint32(16), out=k)
        h ^= k
    out = np.empty(m, np.float32) if work is None else work.get("unit", m, np.float32)
    return np.multiply(h, np.float32(1.0 / 4294967296.0), out=out, dtype=np.float32, casting="unsafe")


class _Work(threading.local):
    """Per-thread scratch arrays of the sink, reused from call to call: fresh multi-megabyte
    temporaries per slice cost more in page faults than the arithmetic on them (measured:
    docs/bake.md, "Bounces in an enclosed room")."""

    def __init__(self) -> None:
        self.arrays: dict[str, np.ndarray] = {}

    def get(self, name: str, m: int, dtype, rows: int = 0) -> np.ndarray:
        """An (m,) or (rows, m) array of dtype, uninitialised."""
        have = self.arrays.get(name)
        if have is None or have.shape[-1] < m or have.dtype != dtype:
            have = self.arrays[name] = np.empty((rows, max(m, 1024)) if rows else max(m, 1024), dtype)
        return have[..., :m] if rows else have[:m]


class HitTransport:
    """Turns a shadow pass's hits into transport entries (the `hit_sink` of a TransferComputation).

    vertices, triangles: the occluder's triangle soup (the primitive ids the occluder returns
    index `triangles`); node_triangles: (T, 3) the node of each triangle corner (-1: the triangle
    reflects nothing); albedo: a scalar, (T,) or (T, C) diffuse albedo per triangle, clamped to
    [0, 1]; n_dirs: the size of the direction set; orientation: None or (T,) +1 / -1, the sign
    by which a triangle's winding normal (b - a) x (c - a) points out of its front face.
    """

    def __init__(
        self,
        vertices: npt.ArrayLike,
        triangles: npt.ArrayLike,
        node_triangles: npt.ArrayLike,
        albedo: npt.ArrayLike,
        n_dirs: int,
        seed: int = 0,
        orientation: npt.ArrayLike | None = None,
    ) -> None:
        v = np.asarray(vertices, dtype=np.float32).reshape(-1, 3)
        t = np.asarray(triangles).reshape(-1, 3)
        nodes = np.asarray(node_triangles, dtype=np.int32).reshape(-1, 3)
        if len(nodes) != len(t):
            raise ValueError("node_triangles must have one row per triangle")
        flip = None if orientation is None else np.flatnonzero(np.asarray(orientation).reshape(-1) < 0)
        self._flipped = flip
        if flip is not None and len(flip):
            # A triangle whose winding is reversed (a mirrored object) is stored as (a, c, b), so
            # that (b - a) x (c - a) points out of every front face.
            t, nodes = t.copy(), nodes.copy()
            t[flip], nodes[flip] = t[flip][:, [0, 2, 1]], nodes[flip][:, [0, 2, 1]]
        # (T, 9) rows (a, b - a, c - a): one take() of 36-byte rows per batch of hits.
        self.corners = np.take(v, t, axis=0).reshape(-1, 9)
        self.corners[:, 3:6] -= self.corners[:, 0:3]
        self.corners[:, 6:9] -= self.corners[:, 0:3]
        self.node_triangles = nodes
        self._corner_nodes = nodes.reshape(-1)  # node of corner j of triangle p at 3 p + j
        self._all_nodes = not np.any(self._corner_nodes < 0)
        rho = np.asarray(albedo, dtype=np.float64)
        rho = np.broadcast_to(rho, (len(t), 1)) if rho.ndim == 0 else rho.reshape(len(t), -1)
        self.albedo = np.clip(np.nan_to_num(rho, nan=0.0), 0.0, 1.0).astype(np.float32)
        self.channels = self.albedo.shape[1]
        self.scale = 4.0 / float(n_dirs)
        self._weights = (self.albedo * np.float32(self.scale)).astype(np.float32)  # per triangle
        self.seed = int(seed)
        # None, or a callable (prims, u det, v det, det) -> None | (which, nodes) giving some hits
        # their nodes by another rule (core.transfer.texel_hits: the texels of texel-baked meshes).
        self.remap = None
        self.hit_albedo: HitAlbedo | None = None  # textured triangles: set_hit_albedo()
        self._work = _Work()

    def set_hit_albedo(self, hit_albedo: HitAlbedo) -> None:
        """Textured triangles take their albedo at each hit from their image (a HitAlbedo over
        the soup as given, before the mirrored triangles' corners were reordered)."""
        if self._flipped is not None and len(self._flipped):
            hit_albedo.flip(self._flipped)
        self.hit_albedo = hit_albedo if hit_albedo.textured else None

    def __call__(
        self,
        rows: np.ndarray,
        kdir: np.ndarray,
        dirs: np.ndarray,
        cosines: np.ndarray,
        prims: np.ndarray,
        origins: np.ndarray,
    ) -> tuple[RowRuns | np.ndarray, np.ndarray, np.ndarray]:
        """(rows, nodes int32, weights (m, C) float32) of the hits (rows as RowRuns, or an int32
        array if they were not sorted): point `rows[j]`'s ray from `origins[j]` along `dirs[j]`,
        with max(0, n . w) `cosines[j]`, hit triangle `prims[j]` first."""
        prims = np.asarray(prims)
        rows = np.asarray(rows)
        work, m = self._work, len(prims)
        # (mode "clip" on valid indices: a take into `out` with the default mode "raise" is
        # buffered, which cost as much again as the take.)
        buffer = work.get("corners", 9 * m, np.float32).reshape(m, 9)
        corners = np.take(self.corners, prims, axis=0, out=buffer, mode="clip")
        ud, vd, det = hit_barycentrics(corners, origins, dirs, work)
        remapped = None if self.remap is None else self.remap(prims, ud, vd, det)  # (before ud, vd change)
        hit = self.hit_albedo
        if hit is not None:  # (the barycentrics of corners 1 and 2; det <= 0 only on back faces, dropped)
            safe = np.where(det > 0.0, det, np.float32(1.0))
            b1, b2 = ud / safe, vd / safe
        xd = _hash_unit(rows, np.asarray(kdir), self.seed, work)
        # Corner 1 where xi < u, 2 where u <= xi < u + v, else 0; compared times det (> 0 on the
        # front faces, the only hits kept), which saves the division.
        xd *= det
        first = np.less(xd, ud, out=work.get("first", m, np.bool_))
        vd += ud
        second = np.less(xd, vd, out=work.get("second", m, np.bool_))
        second |= first  # (u + v < u only off the triangle, by rounding: corner 1 then)
        index = np.multiply(prims, np.int32(3), out=work.get("index", m, prims.dtype))
        index += second
        index += second
        index -= first
        nodes = np.take(self._corner_nodes, index, mode="clip")  # (a third of the indexing's time)
        keep = np.greater(det, 0.0, out=work.get("keep", m, np.bool_))  # det = -w . ((b - a) x (c - a)): a front face
        if remapped is not None:
            nodes[remapped[0]] = remapped[1]
            keep &= nodes >= 0
        elif not self._all_nodes:
            keep &= nodes >= 0
        cosines = np.asarray(cosines)
        if not keep.all():
            prims, cosines, rows, nodes = prims[keep], cosines[keep], rows[keep], nodes[keep]
            if hit is not None:
                b1, b2 = b1[keep], b2[keep]
        weights = np.take(self._weights, prims, axis=0, mode="clip")
        if hit is not None:
            which, rho = hit(prims, b1, b2)
            weights[which] = rho[:, : self.channels] * np.float32(self.scale)
        weights *= cosines.astype(np.float32)[:, None]
        rows = rows.astype(np.int32)
        # A block's rays are point-major, so its rows come sorted: kept as runs (4 bytes a hit less).
        runs = RowRuns(rows) if len(rows) < 2 or not np.any(rows[1:] < rows[:-1]) else rows
        return runs, nodes, weights


class LateSink:
    """A hit sink whose HitTransport comes later (set()), so that the shadow pass can start before
    the tables it needs (every part's nodes, the albedo) are read: a slice's hits that arrive
    before are kept as they came, in a callable that makes their entries (the computation calls
    it when it collects the slice, in its caller's thread)."""

    def __init__(self) -> None:
        self.sink: HitTransport | None = None

    def set(self, sink: HitTransport) -> None:
        self.sink = sink

    def __call__(self, *hits):
        sink = self.sink
        return sink(*hits) if sink is not None else functools.partial(self._late, hits)

    def _late(self, hits):
        if self.sink is None:
            raise RuntimeError("the hits were collected before their sink was set")
        return self.sink(*hits)


def hit_barycentrics(corners: np.ndarray, origins: npt.ArrayLike, dirs: npt.ArrayLike, work: _Work | None = None):
    """(u det, v det, det) float32 of rays o + s w meeting triangles with rows (a, e1, e2) of
    `corners` (m, 9), hit = a + u e1 + v e2, by Moller and Trumbore (1997): p = w x e2,
    q = (o - a) x e1, det = e1 . p, u det = (o - a) . p, v det = w . q. With `work`, the
    results are its buffers (valid until its next use in the same thread).

    Component-major copies first: numpy's arithmetic on the strided columns of (m, 9) and
    (m, 3) rows costs about twice the copies and the contiguous arithmetic together (measured).
    """
    m = len(corners)
    buf = np.empty((21, m), np.float32) if work is None else work.get("barycentrics", m, np.float32, 21)
    c, d, t, p = buf[0:9], buf[9:12], buf[12:15], buf[15:18]
    np.copyto(c, corners.T)
    a, e1, e2 = c[0:3], c[3:6], c[6:9]
    np.copyto(d, np.asarray(dirs, dtype=np.float32).T)
    np.copyto(t, np.asarray(origins, dtype=np.float32).T)
    t -= a
    scratch = np.empty(m, np.float32) if work is None else work.get("scratch", m, np.float32)
    _cross_rows(d, e2, scratch, out=p)
    det = _dot_rows(e1, p, scratch, buf[18])
    ud = _dot_rows(t, p, scratch, buf[19])
    vd = _dot_rows(d, _cross_rows(t, e1, scratch, out=p), scratch, buf[20])
    return ud, vd, det


def _cross_rows(a, b, scratch, out=None):
    """a x b for vectors given as 3 component rows (3, m); scratch: an (m,) buffer."""
    if out is None:
        out = np.empty((3, len(scratch)), dtype=np.float32)
    for i, (j, k) in enumerate(((1, 2), (2, 0), (0, 1))):
        np.multiply(a[j], b[k], out=out[i])
        np.multiply(a[k], b[j], out=scratch)
        out[i] -= scratch
    return out


def _dot_rows(a, b, scratch, out):
    np.multiply(a[0], b[0], out=out)
    for i in (1, 2):
        np.multiply(a[i], b[i], out=scratch)
        out += scratch
    return out


class RowRuns:
    """The rows of sorted entries as runs: row ids[k] repeated counts[k] times (`+=` shifts them)."""

    __slots__ = ("ids", "counts")

    def __init__(self, rows: np.ndarray) -> None:
        start = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]]) if len(rows) else np.zeros(0, np.intp)
        self.ids = rows[start].astype(np.int32)
        self.counts = np.diff(np.r_[start, len(rows)]).astype(np.int64)

    @classmethod
    def from_runs(cls, ids: np.ndarray, counts: np.ndarray) -> RowRuns:
        runs = cls.__new__(cls)
        runs.ids = np.asarray(ids).astype(np.int32)
        runs.counts = np.asarray(counts, dtype=np.int64)
        return runs

    def __len__(self) -> int:
        return int(self.counts.sum())

    def __iadd__(self, offset):
        self.ids += offset
        return self

    def expand(self) -> np.ndarray:
        return np.repeat(self.ids, self.counts)
