"""What a transfer computation counts (rays traced and skipped, and why), what it returns, how
its error estimate is grouped and calibrated (core.transfer.quadrature explains the estimate), and
the loop that steps one to its end."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np


class Cancelled(Exception):
    """Raised by TransferComputation.run() when cancel() was called."""


@dataclass
class TransferStats:
    points: int = 0
    candidate_rays: int = 0  # points * directions
    rays_traced: int = 0
    skipped_below_horizon: int = 0
    skipped_unoccludable: int = 0  # above the horizon, but nothing can occlude the point
    skipped_shadows_off: int = 0  # above the horizon, shadows disabled
    occluded_rays: int = 0
    seconds: float = 0.0
    trace_seconds: float = 0.0  # summed over threads

    @property
    def rays_skipped(self) -> int:
        return self.skipped_below_horizon + self.skipped_unoccludable + self.skipped_shadows_off

    def add(self, other: TransferStats) -> TransferStats:
        for name in (
            "points",
            "candidate_rays",
            "rays_traced",
            "skipped_below_horizon",
            "skipped_unoccludable",
            "skipped_shadows_off",
            "occluded_rays",
            "seconds",
            "trace_seconds",
        ):
            setattr(self, name, getattr(self, name) + getattr(other, name))
        return self

    def as_dict(self) -> dict[str, int | float]:
        return {
            "points": self.points,
            "rays_traced": self.rays_traced,
            "rays_skipped": self.rays_skipped,
            "skipped_below_horizon": self.skipped_below_horizon,
            "skipped_unoccludable": self.skipped_unoccludable,
            "skipped_shadows_off": self.skipped_shadows_off,
            "occluded_rays": self.occluded_rays,
            "seconds": self.seconds,
        }


@dataclass
class TransferResult:
    coeffs: np.ndarray  # (P, n*n) float32
    error: np.ndarray  # (P,) float32: per-point standard-error estimate (L2 over coefficients)
    stats: TransferStats = field(default_factory=TransferStats)

    def error_rms(self) -> float:
        return float(np.sqrt(np.mean(np.square(self.error, dtype=np.float64)))) if len(self.error) else 0.0

    def square_norm_sum(self) -> float:
        """sum over points of |t|^2, accumulated in float64."""
        return float(np.einsum("ij,ij->", self.coeffs, self.coeffs, dtype=np.float64))

    def error_relative(self) -> float:
        """RMS error estimate over RMS transfer norm (dimensionless)."""
        if not len(self.error):
            return 0.0
        norm = np.sqrt(self.square_norm_sum() / len(self.coeffs))
        return self.error_rms() / norm if norm > 0 else 0.0


def error_groups(kind: str) -> int:
    """K, the number of interleaved groups of the batch-means error estimate (module docstring):
    8 for i.i.d. directions (UNIFORM), 2 (halves) for the Fibonacci and stratified sets."""
    return 8 if str(kind).upper() == "UNIFORM" else 2


def error_calibration(kind: str, count: int, order: int) -> float:
    """Factor applied to the batch-means estimate (module docstring; for the Fibonacci set,
    which uses two halves, that is |t_A - t_B| / 2) (docs/accuracy.md).

    1 for i.i.d. and stratified sets (unbiased). For the Fibonacci set the halves are worse than
    the whole by more than sqrt(2): quasi-Monte-Carlo error falls faster than N^-1/2, and when
    N / 2 nears the n^2 coefficients the halves alias. Measured on Suzanne and a torus on a
    ground plane (orders 2-8, 64-4096 directions) the raw ratio estimate / true error was
    1.4-2.0 for N >= 4 n^2 and up to 7 at N = n^2; fitted: raw ratio ~ 1.5 (1 + 3.5 (n^2 / N)^2).
    Dividing by it leaves 0.9-1.8 on those scenes (tests/blender/test_extreme.py::
    test_error_estimate_within_a_factor_of_two_on_a_reference_scene).
    """
    if str(kind).upper() != "FIBONACCI":
        return 1.0
    return 1.0 / (1.5 * (1.0 + 3.5 * (order * order / max(int(count), 1)) ** 2))


def run_to_end(computation: Any, progress: Callable[[float], object] | None = None) -> TransferResult:
    """Step a computation (step, fraction, close, result) to its end, closing it on any exit."""
    try:
        while computation.step():
            if progress is not None:
                progress(computation.fraction)
    finally:
        computation.close()
    return computation.result()
