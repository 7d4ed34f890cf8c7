"""Transfer averaged over several sample positions per element, the direction set split between them.

A texel of a lightmap is an area, not a point: Cycles' image bake averages over its footprint. With
S sample positions x_s per texel and the direction set split into S interleaved subsets
D_s = {w_k : k = s mod S}, the texel's transfer is the mean of the S subsets' own quadratures,

    t_i = 1/S sum_s 4 pi / |D_s| sum_{w in D_s} T(x_s, w) y_i(w)

(= 4 pi / N sum_s sum_{w in D_s} ... for |D_s| = N / S): the texel costs the N rays of one point,
and where the S samples see the same (an open texel) t is exactly the full set's quadrature at a
point. Each subset is its own TransferComputation over sample s of every texel and only the
directions D_s (so the horizon and the projection run over traced directions only), one after
the other on the same threads, all adding into one float32 array (`accumulate`): the samples'
own coefficients are never stored. The error estimate is the root of the sum of the subsets'
squared estimates over S^2.

Interreflection: with a hit_sink every subset gives its blocked rays to it, the element's rows
for all S; a sink weighting each hit 4 / N (N the full set's directions, core.transfer.bounce_hits)
then gives each sample's hits the weight 1 / S of the mean above, as its share of the directions.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np
import numpy.typing as npt

from ..sh.directions import DirectionSet
from .quadrature import TransferComputation
from .stats import TransferResult, TransferStats, run_to_end


def direction_subsets(directions: DirectionSet, count: int) -> list[DirectionSet]:
    """The S = count interleaved subsets of a direction set (k mod S), each a DirectionSet, made
    once per set and count (every object of a texel bake, and each adaptive pass, shares them and
    the SH tables they cache)."""
    count = max(1, min(int(count), directions.count))
    cached = directions._subsets.get(count)
    if cached is not None:
        return cached
    subsets = directions._subsets[count] = []
    for s in range(count):
        picked = np.ascontiguousarray(directions.directions[s::count])
        subsets.append(DirectionSet(directions.kind, len(picked), directions.seed, picked))
    return subsets


class SplitComputation:
    """The transfer of P elements with S sample positions each (module docstring), with the
    interface of TransferComputation (step, start, close, cancel, done, total, fraction, stats,
    coeffs, error, result, run, iter_rays). positions, normals: (S, P, 3); offset and
    self_occludes: scalars, (P,) or (S, P); other options as TransferComputation's."""

    def __init__(
        self,
        positions: npt.ArrayLike,
        normals: npt.ArrayLike,
        directions: DirectionSet,
        order: int,
        **options: Any,
    ) -> None:
        positions = np.asarray(positions, dtype=np.float64)
        normals = np.asarray(normals, dtype=np.float64)
        if positions.ndim != 3 or positions.shape != normals.shape or positions.shape[2] != 3:
            raise ValueError(f"positions and normals must be (S, P, 3) arrays, got {positions.shape}, {normals.shape}")
        self.samples = min(len(positions), directions.count)
        count = positions.shape[1]
        self.order = order
        self._count = count
        per_sample = {}
        for name in ("offset", "self_occludes"):
            if name in options:
                value = np.asarray(options.pop(name))
                per_sample[name] = value if value.ndim == 2 else np.broadcast_to(value, (self.samples, count))
        self._own_pool = options.get("pool") is None
        if self._own_pool:
            options["pool"] = ThreadPoolExecutor(max(1, int(options.get("threads", 2))), thread_name_prefix="prt-bake")
        self._pool = options["pool"]
        self.coeffs = np.zeros((count, order * order), dtype=np.float32)
        self._parts = [
            TransferComputation(
                positions[s],
                normals[s],
                subset,
                order,
                accumulate=self.coeffs,
                accumulate_weight=1.0 / self.samples,
                **{name: value[s] for name, value in per_sample.items()},
                **options,
            )
            for s, subset in enumerate(direction_subsets(directions, self.samples))
        ]
        self._current = 0
        self._started: float | None = None
        self._seconds = 0.0

    @property
    def hits(self) -> list:
        """The hit sink's entries of every subset (rows: the elements; core.transfer.bounce)."""
        return [entry for part in self._parts for entry in part.hits]

    @hits.setter
    def hits(self, value: list) -> None:
        if value:
            raise ValueError("a split computation's hits can only be cleared")
        for part in self._parts:
            part.hits = []

    @property
    def total(self) -> int:
        return self._count

    @property
    def done(self) -> int:
        return sum(part.done for part in self._parts) // self.samples

    @property
    def fraction(self) -> float:
        return sum(part.fraction for part in self._parts) / self.samples

    @property
    def fully_queued(self) -> bool:
        return self._current == len(self._parts) - 1 and self._parts[-1].fully_queued

    @property
    def stats(self) -> TransferStats:
        stats = TransferStats()
        for part in self._parts:
            stats.add(part.stats)
        stats.points = self._count
        stats.seconds = self._seconds
        return stats

    @property
    def error(self) -> np.ndarray:
        squares = np.zeros(self._count, np.float64)
        for part in self._parts:
            squares += np.square(part.error, dtype=np.float64)
        return (np.sqrt(squares) / self.samples).astype(np.float32)

    def cancel(self) -> None:
        for part in self._parts:
            part.cancel()

    def start(self) -> None:
        if self._started is None:
            self._started = time.perf_counter()
        self._parts[self._current].start()

    def step(self) -> bool:
        self.start()
        part = self._parts[self._current]
        more = part.step()
        following = self._current + 1 < len(self._parts)
        if more and following and part.queued >= part.total:
            self._parts[self._current + 1].start()  # (its slices queue behind the last ones: no thread waits)
        elif not more and following:
            self._current += 1
            self._parts[self._current].start()
            more = True
        self._seconds = time.perf_counter() - (self._started or 0.0)
        return more

    def close(self) -> None:
        for part in self._parts:
            part.close()
        if self._own_pool and self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    def result(self) -> TransferResult:
        return TransferResult(self.coeffs, self.error, self.stats)

    def iter_rays(self) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Every (origins, directions) batch traced, in the same order (benchmarks)."""
        for part in self._parts:
            yield from part.iter_rays()

    def run(self, progress: Callable[[float], object] | None = None) -> TransferResult:
        """Compute everything; progress(fraction) after each chunk."""
        return run_to_end(self, progress)
