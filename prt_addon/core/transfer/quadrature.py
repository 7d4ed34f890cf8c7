"""Diffuse transfer vectors by Monte-Carlo projection over a shared direction set.

For a surface point x with unit normal n, the diffuse transfer is T(w) = max(0, n . w) / pi,
times V(x, w) when shadowed (V = 1 if the ray x -> w is free), and its SH projection over the
N equal-weight directions w_k of a DirectionSet is

    t_i = 4 pi / N * sum_k T(w_k) y_i(w_k).

Radiance under lighting L (SH coefficients L_i, albedo applied later) is sum_i L_i t_i.

Work skipped (counted in TransferStats, never traced): directions with n . w <= 0 (T = 0), and
every direction of a point where nothing can occlude (its own mesh cannot, `self_occludes`, see
core.trace.raytrace.cannot_self_occlude, and none of the other occluders' boxes reaches above its
tangent plane).

Error estimate (batch means): the set is split into K interleaved groups G_g (k mod K), each an
unbiased quadrature t_g, and SE(t)^2 ~ sum_g (t_g - mean_g t_g)^2 / (K (K - 1)): K = 8 for i.i.d.
directions, 2 for the Fibonacci and stratified sets, whose raw estimate error_calibration()
corrects (core.transfer.stats); per point, the L2 norm over the coefficients.

Memory and threads (docs/bake.md): slices of at most chunk_rays / threads candidate rays per
thread (RAY_BYTES each, (K + 3) n^2 float64 per point), queued ahead on worker threads.
Interreflection (core.transfer.bounce): with a hit_sink, the blocked rays of the first ceil(K / 2)
error groups go to the sink with their weights times N / hit_end, kept per slice (self.hits).
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor, wait as futures_wait
from typing import Any

import numpy as np
import numpy.typing as npt

from ..serial_blas import matmul_serial
from ..sh.basis import check_order
from ..sh.directions import DirectionSet
from ..trace.ray_rows import RAY16 as _RAY16, rays16 as _rays16, xyz as _xyz
from ..trace.raytrace import box_can_occlude
from .contact import inward_tangents
from .mesh import unit_normals
from .stats import Cancelled, TransferResult, TransferStats, error_calibration, error_groups, run_to_end

CHUNK_RAYS = 1 << 18
SLICES_PER_THREAD = 4  # slices per step() and thread
# Working memory per candidate ray (one point-direction pair of a slice): per-thread buffers
# reused across slices, weight f64 (8), horizon mask (1), directions (16), origins (16), point
# and hit indices (8); per traced ray, the flat indices (8), Embree's int32 result and the hit
# mask (5). Checked with tracemalloc in tests/core/test_transfer_tracing.py.
RAY_BYTES = 80
# The last workspace made in each thread: the computations of one job (several objects, the
# direction subsets of a texel bake) reuse it instead of touching fresh pages each.
_THREAD = threading.local()


class TransferComputation:
    """Transfer vectors of P points, computed chunk by chunk (step()) or at once (run()).

    positions, normals: (P, 3) world-space; normals need not be unit (zero normals give t = 0).
    occluder: None (unshadowed) or a core.trace.occluders.Occluder; offset: ray origin offset
    along the normal, scalar or (P,) (docs/bake.md); self_occludes: bool or (P,), whether the
    points' own mesh can occlude them; other_boxes: (K, 2, 3) boxes of the other occluders for
    culling (None: unknown, every point is traced); pool: a ThreadPoolExecutor to share (else
    one is made, shut down by close()). surface: None or (vertices, triangles) of the points'
    own mesh, point_vertex the vertex of each point (None: point i is vertex i): each origin is
    also moved by `offset` into its own surface (inward_tangents), off the plane of a surface
    that touches it (docs/bake.md, "Contacts"). accumulate: None, or a (P, n*n) float32 array
    that each slice's t times accumulate_weight is added into (it is then self.coeffs: several
    computations sum into one array without each keeping its own; core.transfer.split).
    """

    def __init__(
        self,
        positions: npt.ArrayLike,
        normals: npt.ArrayLike,
        directions: DirectionSet,
        order: int,
        occluder: Any = None,
        offset: npt.ArrayLike = 0.0,
        self_occludes: npt.ArrayLike = True,
        other_boxes: npt.ArrayLike | None = None,
        chunk_rays: int = CHUNK_RAYS,
        threads: int = 2,
        pool: ThreadPoolExecutor | None = None,
        surface: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
        point_vertex: npt.ArrayLike | None = None,
        hit_sink: Callable[..., tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None,
        accumulate: np.ndarray | None = None,
        accumulate_weight: float = 1.0,
    ) -> None:
        if not isinstance(directions, DirectionSet):
            raise TypeError("directions must be a DirectionSet (core.sh.directions.make_directions)")
        self.order = check_order(order)
        self.positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        self.normals = unit_normals(normals)
        if len(self.positions) != len(self.normals):
            raise ValueError("positions and normals must have the same length")
        count = len(self.positions)
        self.occluder = occluder
        # Interleaved error groups g = k mod K, stored group by group so that each is a slice.
        dirs = directions.directions
        basis = directions.basis(self.order)
        self.n_dirs = len(dirs)
        groups = min(error_groups(directions.kind), self.n_dirs)
        members = [np.arange(g, self.n_dirs, groups) for g in range(groups)]
        self.group_bounds = np.cumsum([0] + [len(m) for m in members])
        self.error_scale = error_calibration(directions.kind, self.n_dirs, self.order)
        perm = np.concatenate(members)
        dirs64 = np.ascontiguousarray(dirs[perm])
        self.dirs16 = _rays16(dirs64)
        self.dirs64T = np.ascontiguousarray(dirs64.T)
        self.basis = np.ascontiguousarray(basis[perm])
        offset = np.broadcast_to(np.asarray(offset, dtype=np.float64), (count,))
        lift = self.normals
        if surface is not None:
            lift = lift + inward_tangents(self.positions, self.normals, surface[0], surface[1], point_vertex)
        self.origins16 = _rays16(self.positions + offset[:, None] * lift)
        self.self_occludes = np.broadcast_to(np.asarray(self_occludes, dtype=bool), (count,))
        self.other_boxes = None if other_boxes is None else np.asarray(other_boxes, np.float64).reshape(-1, 2, 3)
        self.chunk_rays = max(1, int(chunk_rays))
        self.threads = max(1, int(threads))
        if occluder is not None:
            self.threads = max(1, min(self.threads, int(getattr(occluder, "max_threads", 1))))
        # chunk_rays candidate rays in flight in all threads together.
        per_thread = max(1, self.chunk_rays // self.threads)
        accumulator_bytes = (groups + 3) * self.order * self.order * 8  # per point of a slice
        self.points_per_slice = max(1, per_thread * RAY_BYTES // (self.n_dirs * RAY_BYTES + accumulator_bytes))
        self.dir_block = min(self.n_dirs, per_thread)
        nn = self.order * self.order
        if accumulate is not None and (accumulate.shape != (count, nn) or accumulate.dtype != np.float32):
            raise ValueError(f"accumulate must be a ({count}, {nn}) float32 array")
        self._accumulate_weight = float(accumulate_weight) if accumulate is not None else None
        self.coeffs = np.zeros((count, nn), dtype=np.float32) if accumulate is None else accumulate
        self.error = np.zeros(count, dtype=np.float32)
        self.stats = TransferStats(points=count, candidate_rays=count * self.n_dirs)
        self.done = 0
        self._local = threading.local()
        self._cancel = False
        self._pool = pool
        self._own_pool = pool is None
        self._pending: deque[tuple[int, int, Future]] = deque()  # (lo, hi, future) of queued slices, in point order
        self._next = 0  # first point not yet queued
        self._started: Any = None  # perf_counter() at the first step
        self.hit_sink = hit_sink
        self.hits: list[Any] = []  # the sink's entries, one tuple per slice
        self.hit_end = int(self.group_bounds[-(-groups // 2)]) if hit_sink is not None else 0
        self.hit_weight = self.n_dirs / self.hit_end if self.hit_end else 0.0

    @property
    def total(self) -> int:
        return len(self.positions)

    @property
    def fraction(self) -> float:
        return self.done / self.total if self.total else 1.0

    @property
    def queued(self) -> int:
        """Points whose slices are queued or done (the first not yet queued)."""
        return max(self._next, self.done)

    @property
    def fully_queued(self) -> bool:
        """Whether every slice is queued or done: the next computation may queue behind it."""
        return self.queued >= self.total

    def cancel(self) -> None:
        self._cancel = True

    def close(self) -> None:
        for _a, _b, future in self._pending:
            future.cancel()
        futures_wait([f for _a, _b, f in self._pending])
        self._pending.clear()
        if self._pool is not None and self._own_pool:
            self._pool.shutdown(wait=True)
            self._pool = None
        # A job keeps every computation until it writes: drop the scratch buffers (~11 MB).
        self._local = threading.local()

    def _needs_rays(self, lo, hi):
        if self.occluder is None:
            return np.zeros(hi - lo, dtype=bool)
        needs = np.array(self.self_occludes[lo:hi])
        if self.other_boxes is None:
            needs[:] = True
        elif len(self.other_boxes):
            needs |= box_can_occlude(self.positions[lo:hi], self.normals[lo:hi], self.other_boxes)
        return needs

    def _workspace(self):
        """Per-thread buffers, reused for every slice: allocating fresh multi-megabyte arrays
        per slice cost more than the numpy work itself (page faults on first touch)."""
        ws = getattr(self._local, "ws", None)
        if ws is None:
            size = self.points_per_slice * self.dir_block
            shared = getattr(_THREAD, "ws", None)  # (a previous computation's, in this thread)
            if shared is not None and len(shared["weight"]) >= size:
                self._local.ws = shared
                return shared
            ws = self._local.ws = _THREAD.ws = {
                "weight": np.empty(size),
                "above": np.empty(size, dtype=bool),
                "dirs": np.empty(size, dtype=_RAY16),
                "origins": np.empty(size, dtype=_RAY16),
                "index": np.empty(size, dtype=np.intp),
            }
        return ws

    def _block(self, lo, hi, k0, k1, needs):
        """Directions [k0, k1) of points [lo, hi): (weight, n_above, flat, origins, dirs).

        weight is max(0, n . w) (T * pi), (hi - lo, k1 - k0) float64; `flat` are the flat
        indices into weight of the rays to trace (above the horizon, at points that need rays),
        point-major, and origins/dirs those rays as (n,) 16-byte rows (ray_rows). weight,
        origins and dirs are per-thread buffers, valid until the next call in the same thread.
        """
        ws = self._workspace()
        n_pts, cols = hi - lo, k1 - k0
        size = n_pts * cols
        weight = ws["weight"][:size].reshape(n_pts, cols)
        matmul_serial(self.normals[lo:hi], self.dirs64T[:, k0:k1], out=weight)
        above = ws["above"][:size].reshape(n_pts, cols)
        np.greater(weight, 0.0, out=above)
        np.maximum(weight, 0.0, out=weight)
        if not needs.any():  # unshadowed slice: nothing to trace
            empty = np.empty(0, dtype=_RAY16)
            return weight, int(np.count_nonzero(above)), np.empty(0, dtype=np.intp), empty, empty
        n_above = int(np.count_nonzero(above))  # (a count per point, axis=1, cost 20 times as much)
        if not needs.all():
            above[~needs] = False
        flat = np.flatnonzero(above)
        # Rays are point-major: each origin is repeated once per direction it traces (a take()
        # by flat // cols into a reused buffer: np.repeat's fresh array cost twice as much; mode
        # clip, as the indices are in range: "raise" takes into a temporary, then copies); the
        # direction is flat - cols (flat // cols), 4 times cheaper than an integer remainder; for
        # a power-of-two cols (256 directions, 64 per texel sample) a shift and a mask, cheaper still.
        index, out = ws["index"][: len(flat)], ws["origins"][: len(flat)]
        if cols & (cols - 1) == 0:
            shifted = np.right_shift(flat, cols.bit_length() - 1, out=index)
            origins = np.take(self.origins16[lo:hi], shifted, out=out, mode="clip")
            np.bitwise_and(flat, cols - 1, out=index)
        else:
            origins = np.take(self.origins16[lo:hi], np.floor_divide(flat, cols, out=index), out=out, mode="clip")
            np.subtract(flat, np.multiply(index, cols, out=index), out=index)
        dirs = np.take(self.dirs16[k0:k1], index, out=ws["dirs"][: len(flat)], mode="clip")
        return weight, n_above, flat, origins, dirs

    def _blocks(self):
        """(k0, k1) direction blocks of a slice, split at hit_end (bounced bakes)."""
        edges = sorted({0, self.hit_end, self.n_dirs})
        return [(k, min(b, k + self.dir_block)) for a, b in zip(edges, edges[1:]) for k in range(a, b, self.dir_block)]

    def iter_rays(self) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Every (origins, directions) batch the bake traces, in the same order (benchmarks),
        as contiguous (n, 3) float32 arrays."""
        for lo in range(0, self.total, self.points_per_slice):
            hi = min(self.total, lo + self.points_per_slice)
            needs = self._needs_rays(lo, hi)
            if not needs.any():
                continue
            for k0, k1 in self._blocks():
                _w, _n, _t, origins, dirs = self._block(lo, hi, k0, k1, needs)
                if len(origins):
                    yield np.ascontiguousarray(_xyz(origins)), np.ascontiguousarray(_xyz(dirs))

    def _slice(self, lo, hi):
        """Project points [lo, hi): returns (t, err, stats, hit entries) for the slice."""
        stats = TransferStats()
        n_pts = hi - lo
        nn = self.order * self.order
        bounds = self.group_bounds
        sums = np.zeros((len(bounds) - 1, n_pts, nn))  # per error group
        needs = self._needs_rays(lo, hi)
        entries = []
        for k0, k1 in self._blocks():
            weight, n_above, flat, rays_o, rays_d = self._block(lo, hi, k0, k1, needs)
            origins, dirs = _xyz(rays_o), _xyz(rays_d)
            n_trace = len(origins)
            stats.skipped_below_horizon += weight.size - n_above
            if self.occluder is None:
                stats.skipped_shadows_off += n_above
            else:
                stats.skipped_unoccludable += n_above - n_trace
            if n_trace:
                t0 = time.perf_counter()
                keep_hits = k0 < self.hit_end
                if not keep_hits:
                    hit = np.asarray(self.occluder.occluded(origins, dirs), dtype=bool)
                else:
                    prims = self.occluder.nearest_triangles(origins, dirs)
                    hit = np.asarray(prims) >= 0
                stats.trace_seconds += time.perf_counter() - t0
                if hit.shape != (n_trace,):
                    raise RuntimeError(f"occluder returned shape {hit.shape} for {n_trace} rays")
                stats.rays_traced += n_trace
                n_hit = int(np.count_nonzero(hit))
                stats.occluded_rays += n_hit
                if n_hit:  # (a take by the hits' positions: 3 times faster than np.compress, same values)
                    which = np.flatnonzero(hit)
                    hit_flat = np.take(flat, which, out=self._workspace()["index"][:n_hit], mode="clip")
                    if keep_hits:  # (np.divmod: each hit's point and direction in one pass)
                        cosines = weight.reshape(-1)[hit_flat] * self.hit_weight
                        hits = (_xyz(np.take(rays_d, which)), cosines, prims[which], _xyz(np.take(rays_o, which)))
                        row, kdir = np.divmod(hit_flat, k1 - k0)
                        entries.append(self.hit_sink(np.add(row, lo, out=row), np.add(kdir, k0, out=kdir), *hits))
                    weight.reshape(-1)[hit_flat] = 0.0  # (np.put is several times slower)
            # Split the block at the group boundaries of the permuted direction order.
            for g in range(len(bounds) - 1):
                a, b = max(bounds[g], k0), min(bounds[g + 1], k1)
                if a < b:
                    matmul_serial(weight[:, a - k0 : b - k0], self.basis[a:b], sums[g], accumulate=True)
        scale = 4.0  # 4 pi / N * (1 / pi) per direction, times N
        t = sums.sum(axis=0)
        t *= scale / self.n_dirs
        groups = len(bounds) - 1
        if groups > 1:
            # In place (the accumulators are the slice's largest arrays): each group's estimate
            # of t / scale, then its deviation from their mean.
            sums /= np.diff(bounds)[:, None, None]
            sums -= sums.mean(axis=0)
            se2 = np.einsum("gij,gij->i", sums, sums) / (groups * (groups - 1))
            err = (scale * self.error_scale) * np.sqrt(se2)
        else:
            err = np.full(n_pts, np.inf)
        return t, err, stats, entries

    def _submit(self):
        """Queue slices on the pool until `threads * SLICES_PER_THREAD` are pending."""
        if self._pool is None:
            self._pool = ThreadPoolExecutor(self.threads, thread_name_prefix="prt-bake")
        while self._next < self.total and len(self._pending) < self.threads * SLICES_PER_THREAD:
            a, b = self._next, min(self.total, self._next + self.points_per_slice)
            self._pending.append((a, b, self._pool.submit(self._slice, a, b)))
            self._next = b

    def start(self) -> None:
        """Queue the first slices now (threads > 1), so that they run while the caller does
        other work; step() collects them. The wall time (stats.seconds) starts here."""
        if self._started is None:
            self._started = time.perf_counter()
        if self.threads > 1 and self.done < self.total and not self._cancel:
            self._submit()

    def step(self) -> bool:
        """Process one chunk; returns False when every point is done."""
        if self._cancel:
            raise Cancelled()
        if self.done >= self.total:
            return False
        self.start()
        for _ in range(self.threads * SLICES_PER_THREAD):
            if self.threads > 1:
                # Slices stay queued ahead of the one collected, so a worker that finishes takes
                # the next slice at once, also between step() calls: no thread waits for another
                # at chunk boundaries. Only `threads` slices run at a time (the memory bound).
                self._submit()
                a, b, future = self._pending.popleft()
                t, err, stats, entries = future.result()
            else:
                a, b = self.done, min(self.total, self.done + self.points_per_slice)
                t, err, stats, entries = self._slice(a, b)
            if self.hit_sink is not None:  # (a callable: entries the sink could not make yet)
                self.hits.extend(e() if callable(e) else e for e in entries)
            if self._accumulate_weight is None:
                self.coeffs[a:b] = t
            else:
                t *= self._accumulate_weight
                self.coeffs[a:b] += t
            self.error[a:b] = err
            self.stats.add(stats)
            self.done = b
            if self.done >= self.total:
                break
        # Wall time since the first step (workers also run between steps).
        self.stats.seconds = time.perf_counter() - self._started
        return self.done < self.total

    def result(self) -> TransferResult:
        return TransferResult(self.coeffs, self.error, self.stats)

    def run(self, progress: Callable[[float], object] | None = None) -> TransferResult:
        """Compute everything; progress(fraction) is called after each chunk."""
        return run_to_end(self, progress)


def compute_transfer(
    positions: npt.ArrayLike,
    normals: npt.ArrayLike,
    directions: DirectionSet,
    order: int,
    occluder: Any = None,
    **kwargs: Any,
) -> TransferResult:
    """(P, n*n) float32 transfer vectors, per-point error estimates and stats (TransferResult)."""
    return TransferComputation(positions, normals, directions, order, occluder, **kwargs).run()
