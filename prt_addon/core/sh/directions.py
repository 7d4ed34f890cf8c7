"""Sets of N unit directions on the sphere, each of equal weight 4 pi / N, with their SH table.

A set is the shared quadrature of the transfer bake: t_i = 4 pi / N * sum_k T(w_k) y_i(w_k).
Every set is reproducible from (kind, count, seed):

* UNIFORM: i.i.d. uniform on the sphere (z uniform in [-1, 1], phi uniform); error ~ N^-1/2.
* STRATIFIED: jittered equal-area strata. Rows of constant z hold counts that differ by at most
  one; each row's height in z is proportional to its count, so every cell has area exactly
  4 pi / N and one uniform point is drawn per cell (the equal weights stay unbiased for any N).
* FIBONACCI: the spherical Fibonacci point set z_k = 1 - (2k + 1)/N, phi_k = k * golden angle
  (Gonzalez 2010, "Measurement of areas on a sphere using Fibonacci and latitude-longitude
  lattices"), turned by a uniformly random rotation drawn from the seed; seed=None keeps the
  canonical, unrotated set.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..serial_blas import matmul_serial
from .basis import FOUR_PI, check_order, sh_basis

KINDS = ("FIBONACCI", "STRATIFIED", "UNIFORM")
GOLDEN_ANGLE = np.pi * (3.0 - np.sqrt(5.0))


def _from_z_phi(z, phi):
    s = np.sqrt(np.clip(1.0 - z * z, 0.0, None))
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=1)


def uniform_directions(count: int, rng: np.random.Generator) -> np.ndarray:
    return _from_z_phi(rng.uniform(-1.0, 1.0, count), rng.uniform(0.0, 2.0 * np.pi, count))


def stratified_directions(count: int, rng: np.random.Generator) -> np.ndarray:
    rows = max(1, int(round(np.sqrt(count / 2.0))))
    per_row = np.full(rows, count // rows)
    per_row[: count % rows] += 1
    row_of_point = np.repeat(np.arange(rows), per_row)
    column = np.arange(count) - np.repeat(np.cumsum(per_row) - per_row, per_row)
    z_top = 1.0 - 2.0 * np.concatenate([[0], np.cumsum(per_row)[:-1]]) / count
    row_height = 2.0 * per_row / count
    z = z_top[row_of_point] - row_height[row_of_point] * rng.uniform(0.0, 1.0, count)
    phi = 2.0 * np.pi * (column + rng.uniform(0.0, 1.0, count)) / per_row[row_of_point]
    return _from_z_phi(z, phi)


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """Uniformly random 3x3 rotation (QR of a Gaussian matrix with the sign fix, Mezzadri 2007)."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def fibonacci_directions(count: int, rng: np.random.Generator | None = None) -> np.ndarray:
    k = np.arange(count, dtype=np.float64)
    d = _from_z_phi(1.0 - (2.0 * k + 1.0) / count, k * GOLDEN_ANGLE)
    if rng is not None:
        d = matmul_serial(d, random_rotation(rng).T)
    return d


@dataclass
class DirectionSet:
    """`directions` is the seed exercise's dir_table; `basis(order)` its sh_coeff_dir table."""

    kind: str
    count: int
    seed: object
    directions: np.ndarray
    _basis: dict = field(default_factory=dict, repr=False)
    _subsets: dict = field(default_factory=dict, repr=False)  # count -> subsets (core.transfer.split)

    @property
    def weight(self) -> float:
        return FOUR_PI / self.count

    def basis(self, order: int) -> np.ndarray:
        """(N, order**2) SH table at the directions, computed once per order (lower orders slice)."""
        order = check_order(order)
        for cached_order, table in self._basis.items():
            if cached_order >= order:
                return table[:, : order * order]
        table = np.ascontiguousarray(sh_basis(self.directions, order))
        self._basis = {order: table}
        return table


def make_directions(kind: str = "FIBONACCI", count: int = 256, seed: int | None = 0) -> DirectionSet:
    """A reproducible DirectionSet of `count` unit vectors (float64, (count, 3))."""
    kind = str(kind).upper()
    if kind not in KINDS:
        raise ValueError(f"direction set kind must be one of {KINDS}, got {kind!r}")
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
        raise ValueError(f"direction count must be an integer >= 1, got {count!r}")
    count = int(count)
    rng = None if seed is None else np.random.default_rng(seed)
    if kind == "FIBONACCI":
        directions = fibonacci_directions(count, rng)
    else:
        rng = rng if rng is not None else np.random.default_rng(0)
        maker = uniform_directions if kind == "UNIFORM" else stratified_directions
        directions = maker(count, rng)
    return DirectionSet(kind, count, seed, directions)
