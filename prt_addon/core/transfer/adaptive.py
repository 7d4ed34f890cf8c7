"""Adaptive texel sampling: trace a coarse lattice of texels, refine only blocks whose corners disagree.

The texels on the lattice lines L = {0, B, 2B, ...} u {R - 1} of both axes are baked first (every
ray). Each block between two consecutive lines of each axis is then either interpolated or traced:
it is interpolated (bilinearly from its four corner texels, in texel coordinates) when every texel
of the block, edges included, is covered, none has a sample under another surface (a contact), the
texels' normals are within NORMAL_COS of the first corner's, and the corners' transfer vectors agree:

    max_c ||t_c - t_mean|| <= tolerance ||t_mean|| + NOISE_SIGMAS max_c e_c

(L2 over the coefficients: by Parseval, the largest change of radiance under any unit-norm
lighting; e_c the corners' own error estimates, so that Monte-Carlo noise alone does not refine).
Otherwise every texel of the block is traced. The idea is that of lightmappers which interpolate
between agreeing block corners (ands/lightmapper); docs/texels.md has the rays saved and the error
against Cycles.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from .stats import TransferResult, TransferStats, run_to_end

BLOCK = 4  # texels between lattice lines
TOLERANCE = 0.05  # relative disagreement of the corners that still interpolates (docs/texels.md)
NOISE_SIGMAS = 2.0
NORMAL_COS = 0.999  # texel normals within ~2.6 degrees of the block's first corner
CHUNK = 1 << 14  # blocks or texels per numpy pass of decide() and interpolate()


def lattice_lines(resolution: int, block: int) -> np.ndarray:
    """The lattice rows (and columns) of a map: 0, block, 2 block, ..., and resolution - 1."""
    return np.unique(np.append(np.arange(0, resolution, block), resolution - 1))


class AdaptivePlan:
    """Which texels are traced first (lattice), and after their transfer is known, which blocks
    are interpolated: texels (P,) sorted flat indices row * resolution + col, normals (S, P, 3)
    of their samples (zero: under another surface)."""

    def __init__(self, texels: np.ndarray, normals: np.ndarray, resolution: int, block: int = BLOCK) -> None:
        res = int(resolution)
        self.texels = np.asarray(texels, dtype=np.int64)
        rows, cols = np.divmod(self.texels, res)
        self.lines = lattice_lines(res, max(1, int(block)))
        n_blocks = max(1, len(self.lines) - 1)
        on_row, on_col = np.isin(rows, self.lines), np.isin(cols, self.lines)
        self.lattice = np.flatnonzero(on_row & on_col)  # positions into texels
        self.block_row = np.clip(np.searchsorted(self.lines, rows, side="right") - 1, 0, n_blocks - 1)
        self.block_col = np.clip(np.searchsorted(self.lines, cols, side="right") - 1, 0, n_blocks - 1)
        self.block = self.block_row * n_blocks + self.block_col
        self.n_blocks = n_blocks
        # Position of each texel of the map in `texels` (-1: not covered).
        where = np.full(res * res, -1, dtype=np.int64)
        where[self.texels] = np.arange(len(self.texels))
        lo_r, hi_r = self.lines[:-1], self.lines[1:]
        if len(self.lines) == 1:
            lo_r = hi_r = self.lines
        br, bc = np.meshgrid(np.arange(n_blocks), np.arange(n_blocks), indexing="ij")
        br, bc = br.ravel(), bc.ravel()
        r0, r1, c0, c1 = lo_r[br], hi_r[br], lo_r[bc], hi_r[bc]
        self.corners = np.stack(
            [where[r0 * res + c0], where[r0 * res + c1], where[r1 * res + c0], where[r1 * res + c1]], 1
        )
        # Summed-area tables of covered and contact texels: a block must be fully covered, contact-free.
        covered = np.zeros((res, res), dtype=np.int64)
        covered.reshape(-1)[self.texels] = 1
        contact = np.zeros((res, res), dtype=np.int64)
        under = ~np.any(np.asarray(normals), axis=2).all(axis=0)  # some sample has a zero normal
        contact.reshape(-1)[self.texels[under]] = 1

        def rect_sum(grid):
            sat = np.zeros((res + 1, res + 1), dtype=np.int64)
            sat[1:, 1:] = grid.cumsum(0).cumsum(1)
            return sat[r1 + 1, c1 + 1] - sat[r0, c1 + 1] - sat[r1 + 1, c0] + sat[r0, c0]

        area = (r1 - r0 + 1) * (c1 - c0 + 1)
        ok = (rect_sum(covered) == area) & (rect_sum(contact) == 0) & (self.corners >= 0).all(axis=1)
        mean_normal = np.asarray(normals, dtype=np.float64).mean(axis=0)
        mean_normal /= np.maximum(np.linalg.norm(mean_normal, axis=1), 1e-30)[:, None]
        first = mean_normal[np.maximum(self.corners[:, 0], 0)]
        cos = np.einsum("ij,ij->i", mean_normal, first[self.block])
        worst = np.ones(len(ok))
        np.minimum.at(worst, self.block, cos)
        self.geometry_ok = ok & (worst >= NORMAL_COS)
        b = self.block
        self.fr = (rows - r0[b]) / np.maximum(r1 - r0, 1)[b]  # position in the block, 0 to 1
        self.fc = (cols - c0[b]) / np.maximum(c1 - c0, 1)[b]
        self.is_lattice = np.zeros(len(self.texels), dtype=bool)
        self.is_lattice[self.lattice] = True

    def decide(self, coeffs: np.ndarray, error: np.ndarray, tolerance: float = TOLERANCE) -> np.ndarray:
        """(blocks,) bool, True where a block is interpolated; coeffs (P, n*n), error (P,) hold
        the lattice texels' values (other rows are not read). In chunks of CHUNK blocks."""
        agree = self.geometry_ok.copy()
        idx = np.maximum(self.corners, 0)
        for a in range(0, len(idx), CHUNK):
            rows = idx[a : a + CHUNK]
            t = np.asarray(coeffs[rows], dtype=np.float64)  # (chunk, 4, n*n)
            mean = t.mean(axis=1)
            spread = np.linalg.norm(t - mean[:, None], axis=2).max(axis=1)
            noise = np.asarray(error[rows], dtype=np.float64).max(axis=1)
            agree[a : a + CHUNK] &= spread <= tolerance * np.linalg.norm(mean, axis=1) + NOISE_SIGMAS * noise
        return agree

    def interpolate(self, which: np.ndarray, values: np.ndarray, out: np.ndarray) -> None:
        """out[which] = the bilinear values at texels `which` (positions) from the corners of
        their blocks; values (P, C) hold the lattice texels' values (out may be values). In
        chunks of CHUNK texels (a float64 copy of a whole map would be the bake's peak)."""
        for a in range(0, len(which), CHUNK):
            part = which[a : a + CHUNK]
            corners = self.corners[self.block[part]]
            fr, fc = self.fr[part][:, None], self.fc[part][:, None]
            v = [np.asarray(values[corners[:, k]], dtype=np.float64) for k in range(4)]
            out[part] = (1 - fr) * ((1 - fc) * v[0] + fc * v[1]) + fr * ((1 - fc) * v[2] + fc * v[3])


class AdaptiveComputation:
    """The transfer of a texel map's P texels with the interface of SplitComputation: `make`
    (positions into the texels -> a computation over those texels) is called for the lattice and
    then for the texels of the blocks that must be traced."""

    def __init__(
        self,
        plan: AdaptivePlan,
        make: Callable[[np.ndarray], Any],
        order: int,
        tolerance: float = TOLERANCE,
    ) -> None:
        self.plan = plan
        self._make = make
        self.tolerance = float(tolerance)
        count = len(plan.texels)
        self._count = count
        self.coeffs = np.zeros((count, order * order), dtype=np.float32)
        self._error = np.zeros(count, dtype=np.float32)
        self.interpolated = 0  # texels filled by interpolation
        self._refined = False  # whether the lattice's blocks were decided
        self._done_before = 0  # texels final before the current phase
        self._started: float | None = None
        self._seconds = 0.0
        self._stats = TransferStats()
        self.hits: list = []
        self._open(plan.lattice)

    def _open(self, which):
        self._current = (which, self._make(which)) if len(which) else None

    @property
    def total(self) -> int:
        return self._count

    @property
    def done(self) -> int:
        return self._done_before + (self._current[1].done if self._current else 0)

    @property
    def fraction(self) -> float:
        return self.done / self._count if self._count else 1.0

    @property
    def fully_queued(self) -> bool:
        """After the lattice (the blocks to trace need its results), with the rest all queued."""
        return self._refined and (self._current is None or self._current[1].fully_queued)

    @property
    def stats(self) -> TransferStats:
        stats = TransferStats()
        stats.add(self._stats)
        if self._current is not None:
            stats.add(self._current[1].stats)
        stats.points = self._count
        stats.seconds = self._seconds
        return stats

    @property
    def error(self) -> np.ndarray:
        return self._error

    def cancel(self) -> None:
        if self._current is not None:
            self._current[1].cancel()

    def start(self) -> None:
        if self._started is None:
            self._started = time.perf_counter()
        if self._current is not None:
            self._current[1].start()

    def _collect(self):
        which, comp = self._current
        self.coeffs[which] = comp.coeffs
        self._error[which] = comp.error
        self._stats.add(comp.stats)
        self._done_before += len(which)
        comp.close()
        self._current = None

    def step(self) -> bool:
        self.start()
        more = False
        if self._current is not None:
            more = self._current[1].step()
            if not more:
                self._collect()
        if not more and not self._refined:
            self._refined = True
            more = self._refine()
        self._seconds = time.perf_counter() - (self._started or 0.0)
        return more

    def _refine(self) -> bool:
        """After the lattice: interpolate the agreeing blocks, open the computation of the rest."""
        plan = self.plan
        agree = plan.decide(self.coeffs, self._error, self.tolerance)
        rest = ~plan.is_lattice
        fill = np.flatnonzero(rest & agree[plan.block])
        plan.interpolate(fill, self.coeffs, self.coeffs)  # (fill holds no lattice texel)
        plan.interpolate(fill, self._error[:, None], self._error[:, None])
        self.interpolated = len(fill)
        self._done_before += len(fill)
        self._open(np.flatnonzero(rest & ~agree[plan.block]))
        if self._current is None:
            return False
        self._current[1].start()
        return True

    def close(self) -> None:
        if self._current is not None:
            self._current[1].close()

    def result(self) -> TransferResult:
        return TransferResult(self.coeffs, self._error, self.stats)

    def iter_rays(self) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Every (origins, directions) batch the bake traces (benchmarks): the lattice's, then,
        after computing the lattice (to know the blocks), the refined texels'."""
        plan = self.plan
        lattice = self._make(plan.lattice) if len(plan.lattice) else None
        if lattice is not None:
            yield from lattice.iter_rays()
            run_to_end(lattice)
            coeffs = np.zeros_like(self.coeffs)
            error = np.zeros_like(self._error)
            coeffs[plan.lattice], error[plan.lattice] = lattice.coeffs, lattice.error
        else:
            coeffs, error = self.coeffs, self._error
        agree = plan.decide(coeffs, error, self.tolerance)
        rest = np.flatnonzero(~plan.is_lattice & ~agree[plan.block])
        if len(rest):
            refine = self._make(rest)
            yield from refine.iter_rays()
            refine.close()

    def run(self, progress: Callable[[float], object] | None = None) -> TransferResult:
        return run_to_end(self, progress)
