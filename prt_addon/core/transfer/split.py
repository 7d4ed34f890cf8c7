"""Transfer averaged over several sample positions per element, the direction set split between them.

A texel of a lightmap is an area, not a point: Cycles' image bake averages over its footprint. With
S sample positions x_s per texel and the direction set split into S interleaved subsets
D_s = {w_k : k = s mod S}, the texel's transfer is

    t_i = 4 pi / N sum_s sum_{w in D_s} T(x_s, w) y_i(w)

(for |D_s| = N / S, the mean of the S subsets' own quadratures): the texel costs the N rays of
one point, and where the S samples see the same (an open texel) t is exactly the full set's
quadrature at a point. One TransferComputation traces all the samples, texel-major (sample s of
texel p is point p S + s, which sees the subset s: its `subsets` mask); t is the sum over a
texel's samples, its error estimate the root of the sum of their squared estimates.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import numpy.typing as npt

from ..sh.directions import DirectionSet
from .quadrature import TransferComputation
from .stats import TransferResult, TransferStats


def direction_subsets(directions: DirectionSet, count: int) -> list[DirectionSet]:
    """The S = count interleaved subsets of a direction set (k mod S), each a DirectionSet."""
    count = max(1, min(int(count), directions.count))
    subsets = []
    for s in range(count):
        picked = np.ascontiguousarray(directions.directions[s::count])
        subsets.append(DirectionSet(directions.kind, len(picked), directions.seed, picked))
    return subsets


def _interleave(values: np.ndarray) -> np.ndarray:
    """(S, P, ...) -> (P S, ...): sample s of element p at row p S + s."""
    return np.ascontiguousarray(np.swapaxes(values, 0, 1).reshape(-1, *values.shape[2:]))


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
        if options.get("hit_sink") is not None:
            raise ValueError("a split computation keeps no hits (bounces are baked at points)")
        self.samples = min(len(positions), directions.count)
        positions, normals = positions[: self.samples], normals[: self.samples]
        count = positions.shape[1]
        for name in ("offset", "self_occludes"):
            if name in options:
                value = np.asarray(options[name])
                if value.ndim == 1:
                    value = np.broadcast_to(value, (self.samples, count))
                options[name] = _interleave(value) if value.ndim == 2 else value
        self.order = order
        self._count = count
        self._part = TransferComputation(
            _interleave(positions), _interleave(normals), directions, order, subsets=self.samples, **options
        )
        self.hits: list = []

    @property
    def total(self) -> int:
        return self._count

    @property
    def done(self) -> int:
        return self._part.done // self.samples

    @property
    def fraction(self) -> float:
        return self._part.fraction

    @property
    def stats(self) -> TransferStats:
        """The counts of the texels' own rays: each sample's masked-out directions (those of the
        other subsets) are neither candidates nor skipped."""
        stats = TransferStats().add(self._part.stats)
        masked = stats.candidate_rays - stats.candidate_rays // self.samples
        stats.points = self._count
        stats.candidate_rays -= masked
        stats.skipped_below_horizon -= masked * self._part.done // max(1, self._part.total)
        return stats

    @property
    def coeffs(self) -> np.ndarray:
        per_sample = self._part.coeffs.reshape(self._count, self.samples, -1)
        return per_sample.sum(axis=1, dtype=np.float64).astype(np.float32)  # (no float64 copy of all samples)

    @property
    def error(self) -> np.ndarray:
        per_sample = np.asarray(self._part.error, np.float64).reshape(self._count, self.samples)
        return np.sqrt((per_sample**2).sum(axis=1)).astype(np.float32)

    def cancel(self) -> None:
        self._part.cancel()

    def start(self) -> None:
        self._part.start()

    def step(self) -> bool:
        return self._part.step()

    def close(self) -> None:
        self._part.close()

    def result(self) -> TransferResult:
        return TransferResult(self.coeffs, self.error, self.stats)

    def iter_rays(self) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Every (origins, directions) batch traced, in the same order (benchmarks)."""
        return self._part.iter_rays()

    def run(self, progress: Callable[[float], object] | None = None) -> TransferResult:
        """Compute everything (the part's own loop: its fraction is this one's)."""
        self._part.run(progress)
        return self.result()
