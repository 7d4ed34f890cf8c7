"""The back side of open surfaces: which meshes are open, and their bake points and faces turned over.

A single-sided plane (a roof, a wall, a leaf card) is shaded by Cycles on both sides: its back
sees the other half of the sphere. A mesh with a boundary edge (an edge of one triangle) can be
seen from behind, so its back side gets a transfer of its own, baked at the same points for the
flipped normals (docs/bake.md, "Back faces").
"""

from __future__ import annotations

import dataclasses

import numpy as np
import numpy.typing as npt

from .mesh import BakePoints


def boundary_edges(triangles: npt.ArrayLike) -> int:
    """How many undirected edges of these (T, 3) vertex triangles belong to one triangle only."""
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if len(t) == 0:
        return 0
    edges = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    _unique, counts = np.unique(edges[:, 0] * (int(t.max()) + 1) + edges[:, 1], return_counts=True)
    return int(np.count_nonzero(counts == 1))


def is_open(triangles: npt.ArrayLike) -> bool:
    """Whether the mesh has a boundary, i.e. whether its back side can be seen."""
    return boundary_edges(triangles) > 0


def turned_over(points: BakePoints) -> BakePoints:
    """The same points with their normals flipped: the back side's bake points."""
    return dataclasses.replace(points, normals=-np.asarray(points.normals))


def turned_over_triangles(triangles: npt.ArrayLike) -> np.ndarray:
    """The triangles wound the other way (their face normals flipped), as int32."""
    return np.ascontiguousarray(np.asarray(triangles, dtype=np.int32)[:, ::-1])
