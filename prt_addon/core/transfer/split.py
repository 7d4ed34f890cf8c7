"""Transfer averaged over several sample positions per element, the direction set split between them.

A texel of a lightmap is an area, not a point: Cycles' image bake averages over its footprint. With
S sample positions x_s per texel and the direction set split into S interleaved subsets
D_s = {w_k : k = s mod S}, the texel's transfer is

    t_i = 1/S sum_s 4 pi / |D_s| sum_{w in D_s} T(x_s, w) y_i(w)

each term an unbiased quadrature over its own subset: the texel costs the N rays of one point, and
where the S samples see the same (an open texel) t is exactly the full set's quadrature at a point.
Its error estimate is sqrt(sum_s e_s^2) / S from the subsets' own estimates (core.transfer.quadrature).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import numpy.typing as npt

from ..sh.directions import DirectionSet
from .quadrature import TransferComputation
from .stats import Cancelled, TransferResult, TransferStats


def direction_subsets(directions: DirectionSet, count: int) -> list[DirectionSet]:
    """The S = count interleaved subsets of a direction set (k mod S), each a DirectionSet."""
    count = max(1, min(int(count), directions.count))
    subsets = []
    for s in range(count):
        picked = np.ascontiguousarray(directions.directions[s::count])
        subsets.append(DirectionSet(directions.kind, len(picked), directions.seed, picked))
    return subsets


class SplitComputation:
    """The transfer of P elements with S sample positions each: S TransferComputations, the s-th
    over every element's s-th sample and the s-th direction subset, made and run one after the
    other (one part's buffers at a time) and summed as they finish; coeffs and error are their
    combination (module docstring). The same interface as TransferComputation (step, start,
    close, cancel, done, total, fraction, stats, result)."""

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
        if options.get("hit_sink") is not None:
            raise ValueError("a split computation keeps no hits (bounces are baked at points)")
        self._offset = np.asarray(options.pop("offset", 0.0), dtype=np.float64)
        self._self_occludes = np.asarray(options.pop("self_occludes", True))
        self._subsets = direction_subsets(directions, len(positions))
        self._positions, self._normals, self._options = positions, normals, options
        self.order = order
        self.samples = len(self._subsets)
        self._count = positions.shape[1]
        self._sum = np.zeros((self._count, order * order))
        self._square_error = np.zeros(self._count)
        self._stats = TransferStats()
        self._part: TransferComputation | None = None
        self._current = 0  # the part running (== samples when all are done)
        self._cancel = False
        self.hits: list = []

    def _make_part(self, s: int) -> TransferComputation:
        def pick(value: np.ndarray) -> Any:
            return value[s] if value.ndim == 2 else value

        return TransferComputation(
            self._positions[s],
            self._normals[s],
            self._subsets[s],
            self.order,
            offset=pick(self._offset),
            self_occludes=pick(self._self_occludes),
            **self._options,
        )

    def _current_part(self) -> TransferComputation | None:
        if self._part is None and self._current < self.samples:
            self._part = self._make_part(self._current)
        return self._part

    def _collect(self, part: TransferComputation) -> None:
        """Add a finished part's transfer, error and counts, and drop its buffers."""
        part.close()
        self._sum += part.coeffs
        self._square_error += np.asarray(part.error, np.float64) ** 2
        self._stats.add(part.stats)
        self._part = None
        self._current += 1

    @property
    def total(self) -> int:
        return self._count

    @property
    def done(self) -> int:
        """Elements done, counting each sample as 1/S of its element."""
        running = self._part.done if self._part is not None else 0
        return (self._current * self._count + running) // self.samples

    @property
    def fraction(self) -> float:
        return self.done / self._count if self._count else 1.0

    @property
    def stats(self) -> TransferStats:
        total = TransferStats().add(self._stats)
        if self._part is not None:
            total.add(self._part.stats)
        total.points = self._count
        total.candidate_rays = self._count * sum(d.count for d in self._subsets)
        return total

    @property
    def coeffs(self) -> np.ndarray:
        return (self._sum / self.samples).astype(np.float32)

    @property
    def error(self) -> np.ndarray:
        return (np.sqrt(self._square_error) / self.samples).astype(np.float32)

    def cancel(self) -> None:
        self._cancel = True
        if self._part is not None:
            self._part.cancel()

    def start(self) -> None:
        part = self._current_part()
        if part is not None:
            part.start()

    def step(self) -> bool:
        """Process one chunk of the current sample's computation; False when all are done."""
        if self._cancel:
            raise Cancelled()
        part = self._current_part()
        if part is None:
            return False
        if part.step():
            return True
        self._collect(part)
        nxt = self._current_part()
        if nxt is None:
            return False
        nxt.start()
        return True

    def close(self) -> None:
        if self._part is not None:
            self._part.close()

    def result(self) -> TransferResult:
        return TransferResult(self.coeffs, self.error, self.stats)

    def iter_rays(self) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Every (origins, directions) batch traced, in the same order (benchmarks)."""
        for s in range(self.samples):
            part = self._make_part(s)
            yield from part.iter_rays()
            part.close()

    def run(self, progress: Callable[[float], object] | None = None) -> TransferResult:
        try:
            while self.step():
                if progress is not None:
                    progress(self.fraction)
        finally:
            self.close()
        return self.result()
