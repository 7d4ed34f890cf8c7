"""Analytic occluders in pure numpy (a plane, a wall, a cup) with closed-form transfer."""

import numpy as np


class PlaneOccluder:
    """The infinite plane through `point` with normal `normal` (analytic ray test)."""

    name = "PLANE"
    max_threads = 2

    def __init__(self, point, normal):
        self.point = np.asarray(point, float)
        self.normal = np.asarray(normal, float) / np.linalg.norm(normal)

    def occluded(self, origins, directions):
        o, d = origins.astype(np.float64), directions.astype(np.float64)
        denom = d @ self.normal
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((self.point - o) @ self.normal) / denom
        return np.isfinite(t) & (t > 0)


class WallOccluder:
    """A wall in the plane x = d, 0 <= z <= h, infinitely wide in y."""

    name = "WALL"
    max_threads = 2

    def __init__(self, d, h):
        self.d, self.h = d, h

    def occluded(self, origins, directions):
        o, w = origins.astype(np.float64), directions.astype(np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (self.d - o[:, 0]) / w[:, 0]
        z = o[:, 2] + t * w[:, 2]
        return (w[:, 0] > 0) & (t > 0) & (z >= 0) & (z <= self.h)


class CupOccluder:
    """Lower half (z <= 1) of the unit sphere centred at (0, 0, 1): a cup whose bottom is the
    origin and whose rim is the circle of radius 1 at height 1."""

    name = "CUP"
    max_threads = 2

    def occluded(self, origins, directions):
        o, d = origins.astype(np.float64), directions.astype(np.float64)
        oc = o - np.array([0.0, 0.0, 1.0])
        b = np.einsum("ij,ij->i", oc, d)
        c = np.einsum("ij,ij->i", oc, oc) - 1.0
        disc = b * b - c
        t = -b + np.sqrt(np.maximum(disc, 0.0))  # the far root: origins are inside the sphere
        z = o[:, 2] + t * d[:, 2]
        return (disc > 0) & (t > 0) & (z < 1.0)
