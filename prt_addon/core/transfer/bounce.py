"""Interreflected transfer: the blocked rays' hits as a sparse transport, and the bounce passes.

Sloan, Kautz and Snyder 2002 (section 5, interreflected transfer): the light that leaves a
diffuse surface point h after b reflections is rho(h) sum_i L_i t_i^b(h), so one more reflection
reaches a point x with normal n along each blocked direction w of its shadow pass:

    t^{b+1}(x) = 4 pi / N sum_{w blocked, front face hit} max(0, n . w) / pi * rho(h_w) t^b(h_w)

with t^0 the direct (shadowed) transfer and N the directions of the shared set; the bounced
transfer is t^1 + ... + t^B. Every pass reuses the shadow pass's hits (no new rays), and each
pass applies the same sparse matrix A to the previous pass (no bounce is counted twice).

t^b(h) is interpolated over the hit triangle's nodes, one node per hit chosen at random with
the barycentric weights (core.transfer.bounce_hits, which turns the hits into entries).

Memory: one entry per front-face hit while the shadow pass runs (core.transfer.bounce_hits), and the
same in the matrix (plus its padding).
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from concurrent.futures import Executor
from typing import Any

import numpy as np

# The sink side, used with the transport (re-exported: callers build both from here).
from .bounce_hits import RowRuns

# Entry chunks of one matrix-vector product: at most this many float32 gathered values.
GATHER_VALUES = 1 << 22
ROWS_PER_SLICE = 512
# Slices per task of a threaded product: with one task per slice the threads were slower than
# one thread, with 8 faster (measured: docs/bake.md, "Cost").
SLICES_PER_TASK = 8


def _row_span(rows):
    """(first row, last row, sorted) of an entry block's rows (RowRuns or an array)."""
    if isinstance(rows, RowRuns):
        return int(rows.ids[0]), int(rows.ids[-1]), True
    return int(rows[0]), int(rows[-1]), len(rows) < 2 or not np.any(rows[1:] < rows[:-1])


class Transport:
    """A sparse matrix (rows: the points of one computation; columns: nodes) from hit entries;
    apply() is y = A x per colour channel.

    Stored as "sliced ELLPACK": the rows are sorted by their number of entries and cut into
    slices of ROWS_PER_SLICE, each slice a dense (rows, K) block of node indices and weights
    padded with zero weights to its longest row (a few percent of padding, as neighbouring rows
    in that order have nearly the same length). A product is then one gather and one matmul per
    slice, more than 2.5 times faster than numpy's segment sums (np.add.reduceat) over the entries.
    """

    def __init__(self, entries: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]], n_rows: int, channels: int):
        """entries: (rows, nodes, weights) tuples (a list is emptied: it is consumed)."""
        parts: list[tuple[Any, np.ndarray, np.ndarray]] = [e for e in entries if len(e[0])]
        self.n_rows = int(n_rows)
        self.channels = int(channels)
        self.entries = 0
        self.slices = []  # (row ids (S,), nodes (S, K) int32, weights (S, K, C) float32)
        self._work = threading.local()  # each thread's gather buffer
        if not parts:
            return
        spans = [_row_span(p[0]) for p in parts]
        in_order = all(s[2] for s in spans) and all(a[1] <= b[0] for a, b in zip(spans, spans[1:]))
        if in_order:  # (the usual case: slices in point order) the rows as counts, not a copy
            counts = np.zeros(self.n_rows, dtype=np.int64)
            for p in parts:
                runs = p[0] if isinstance(p[0], RowRuns) else RowRuns(p[0])
                counts[runs.ids] += runs.counts
            parts = [(None, p[1], p[2]) for p in parts]
        if isinstance(entries, list):  # consumed: the caller's per-slice arrays are freed now
            entries.clear()
        # One zero-weight entry after the last: the slices' padding points at it.
        nodes = np.concatenate([p[1] for p in parts] + [np.zeros(1, np.int32)])
        weights = np.concatenate([p[2] for p in parts] + [np.zeros((1, parts[0][2].shape[1]), np.float32)])
        if not in_order:
            rows = np.concatenate([p[0].expand() if isinstance(p[0], RowRuns) else p[0] for p in parts])
            counts = np.bincount(rows, minlength=self.n_rows)
            order = np.r_[np.argsort(rows, kind="stable"), len(rows)]  # (the padding entry stays last)
            nodes, weights = nodes[order], weights[order]
            del rows
        del parts
        self.entries = pad = len(nodes) - 1
        first = np.cumsum(counts) - counts  # each row's first entry
        by_length = np.argsort(-counts, kind="stable")
        by_length = by_length[counts[by_length] > 0]
        for s0 in range(0, len(by_length), ROWS_PER_SLICE):
            ids = by_length[s0 : s0 + ROWS_PER_SLICE]
            width = int(counts[ids[0]])
            column = np.arange(width)
            index = first[ids][:, None] + column[None, :]
            np.copyto(index, pad, where=column[None, :] >= counts[ids][:, None])
            self.slices.append((ids.astype(np.intp), np.take(nodes, index), np.take(weights, index, axis=0)))

    @property
    def nbytes(self) -> int:
        return sum(r.nbytes + n.nbytes + w.nbytes for r, n, w in self.slices)

    def _apply_slice(self, x, out, ids, nodes, weights):
        step = max(1, GATHER_VALUES // max(1, nodes.shape[1] * x.shape[1] * x.shape[2]))
        for a in range(0, len(ids), step):
            index = nodes[a : a + step]
            # (S, K, Cx, nn); mode "clip" on valid indices: into `out`, the default "raise" is buffered.
            gathered = np.take(x, index, axis=0, out=self._gather_buffer(index.shape + x.shape[1:]), mode="clip")
            w = weights[a : a + step]
            # Batched matmuls (S, C, 1, K) @ (S, C, K, nn): 2.5 to 7 times faster than einsum.
            if gathered.shape[2] == w.shape[2]:
                out[ids[a : a + step]] = np.matmul(w.transpose(0, 2, 1)[:, :, None, :], gathered.transpose(0, 2, 1, 3))[
                    :, :, 0
                ]
            else:  # Cx = 1: the same x for every channel
                out[ids[a : a + step]] = np.matmul(w.transpose(0, 2, 1), gathered[:, :, 0])

    def _gather_buffer(self, shape):
        """A float32 array of `shape` reused by this thread's products (a fresh one per chunk
        cost more in page faults than the gather itself)."""
        size = int(np.prod(shape))
        have = getattr(self._work, "gather", None)
        if have is None or len(have) < size:
            have = self._work.gather = np.empty(size, np.float32)
        return have[:size].reshape(shape)

    def apply(self, x: np.ndarray, pool: Executor | None = None) -> np.ndarray:
        """A x for x (nodes, 1 or C, nn) float32: (n_rows, C, nn) float32."""
        x = np.asarray(x, dtype=np.float32)
        out = np.zeros((self.n_rows, max(self.channels, x.shape[1]), x.shape[2]), dtype=np.float32)
        if pool is None or len(self.slices) <= SLICES_PER_TASK:
            self._apply_slices(x, out, self.slices)
        else:  # every row is in one slice: the threads write disjoint rows
            tasks = range(0, len(self.slices), SLICES_PER_TASK)
            futures = [pool.submit(self._apply_slices, x, out, self.slices[a : a + SLICES_PER_TASK]) for a in tasks]
            for future in futures:
                future.result()
        return out

    def _apply_slices(self, x, out, slices):
        for piece in slices:
            self._apply_slice(x, out, *piece)


class BouncePasses:
    """The bounce passes of B bounces, one pass per step() (cancellable between passes).

    direct: t^0 of the nodes, (nodes, nn); transport: A (nodes x nodes); extra: transports R of
    receivers that are not nodes. After the last step, `total` is the nodes' bounced transfer
    sum_{b=1..B} A^b t^0, (nodes, C, nn) float32, and `extra_out` each R sum_{b=0..B-1} A^b t^0.
    """

    def __init__(
        self,
        direct: np.ndarray,
        transport: Transport,
        bounces: int,
        extra: Sequence[Transport] = (),
        pool: Executor | None = None,
    ) -> None:
        if int(bounces) < 1:
            raise ValueError("bounces must be at least 1")
        self.direct: Any = np.asarray(direct, dtype=np.float32)[:, None, :]  # None once done
        self.transport, self.bounces, self.extra, self.pool = transport, int(bounces), list(extra), pool
        self.done = 0
        self.term: Any = self.direct  # None once done
        self.total: Any = None
        self.extra_out: list[np.ndarray] = []

    def step(self) -> bool:
        """Run the next pass; False once all are done."""
        if self.done >= self.bounces:
            return False
        if self.done == self.bounces - 1 and self.extra:
            before_last = self.direct if self.total is None else self.total + self.direct
            self.extra_out = [r.apply(before_last, self.pool) for r in self.extra]
        self.term = self.transport.apply(self.term, self.pool)
        if self.total is None:
            self.total = self.term.copy()
        else:
            if self.term.shape[1] > self.total.shape[1]:
                self.total = np.broadcast_to(self.total, self.term.shape).copy()
            self.total += self.term
        self.done += 1
        if self.done == self.bounces:
            self.term = self.direct = None  # (only the total is kept)
        return self.done < self.bounces


def bounce_passes(
    direct: np.ndarray,
    transport: Transport,
    bounces: int,
    extra: Sequence[Transport] = (),
    pool: Executor | None = None,
) -> tuple[np.ndarray, list[np.ndarray]]:
    """(total, extra_out) of BouncePasses, all passes at once."""
    passes = BouncePasses(direct, transport, bounces, extra, pool)
    while passes.step():
        pass
    return passes.total, passes.extra_out
