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
    over every element's s-th sample and the s-th direction subset, run one after the other;
    coeffs and error are their combination (module docstring). The same interface as
    TransferComputation (step, start, close, cancel, done, total, fraction, stats, result)."""

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
        offset = np.asarray(options.pop("offset", 0.0), dtype=np.float64)
        self_occludes = np.asarray(options.pop("self_occludes", True))
        subsets = direction_subsets(directions, len(positions))
        self.order = order
        self.parts = [
            TransferComputation(
                positions[s],
                normals[s],
                subset,
                order,
                offset=offset[s] if offset.ndim == 2 else offset,
                self_occludes=self_occludes[s] if self_occludes.ndim == 2 else self_occludes,
                **options,
            )
            for s, subset in enumerate(subsets)
        ]
        self.samples = len(self.parts)
        self._count = positions.shape[1]
        self._current = 0
        self._cancel = False
        self.hits: list = []

    @property
    def total(self) -> int:
        return self._count

    @property
    def done(self) -> int:
        """Elements done, counting each sample as 1/S of its element."""
        return sum(p.done for p in self.parts) // self.samples

    @property
    def fraction(self) -> float:
        work = sum(p.total for p in self.parts)
        return sum(p.done for p in self.parts) / work if work else 1.0

    @property
    def stats(self) -> TransferStats:
        total = TransferStats()
        for part in self.parts:
            total.add(part.stats)
        total.points = self._count
        total.seconds = sum(p.stats.seconds for p in self.parts)
        return total

    @property
    def coeffs(self) -> np.ndarray:
        out = np.zeros((self._count, self.order * self.order))
        for part in self.parts:
            out += part.coeffs
        return (out / self.samples).astype(np.float32)

    @property
    def error(self) -> np.ndarray:
        square = np.zeros(self._count)
        for part in self.parts:
            square += np.asarray(part.error, np.float64) ** 2
        return (np.sqrt(square) / self.samples).astype(np.float32)

    def cancel(self) -> None:
        self._cancel = True
        for part in self.parts:
            part.cancel()

    def start(self) -> None:
        if self._current < self.samples:
            self.parts[self._current].start()

    def step(self) -> bool:
        """Process one chunk of the current sample's computation; False when all are done."""
        if self._cancel:
            raise Cancelled()
        while self._current < self.samples:
            part = self.parts[self._current]
            if part.step():
                return True
            part.close()
            self._current += 1
            if self._current < self.samples:
                self.parts[self._current].start()
                return True
        return False

    def close(self) -> None:
        for part in self.parts:
            part.close()

    def result(self) -> TransferResult:
        return TransferResult(self.coeffs, self.error, self.stats)

    def iter_rays(self) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Every (origins, directions) batch traced, in the same order (benchmarks)."""
        for part in self.parts:
            yield from part.iter_rays()

    def run(self, progress: Callable[[float], object] | None = None) -> TransferResult:
        try:
            while self.step():
                if progress is not None:
                    progress(self.fraction)
        finally:
            self.close()
        return self.result()
