"""Fallback occluder on mathutils.bvhtree.BVHTree (same protocol as core.raytrace.EmbreeOccluder).

ray_cast() holds the GIL and is called once per ray from Python, so this backend is single
threaded (max_threads = 1) and much slower than Embree (measured in docs/bake.md); it exists for platforms
without an embreex wheel (Linux and Windows on ARM).
"""

import numpy as np
from mathutils.bvhtree import BVHTree

from ..core.raytrace import as_triangles


class BVHTreeOccluder:
    name = "BVHTREE"
    max_threads = 1

    def __init__(self, vertices, triangles):
        v, t = as_triangles(vertices, triangles)
        if len(t) == 0:
            raise ValueError("an occluder needs at least one triangle")
        self.triangle_count = len(t)
        self._corners = (v, t)
        self._tree = BVHTree.FromPolygons(v.tolist(), t.tolist(), all_triangles=True, epsilon=0.0)

    def occluded(self, origins, directions):
        o = np.asarray(origins, dtype=np.float32).tolist()
        d = np.asarray(directions, dtype=np.float32).tolist()
        cast = self._tree.ray_cast
        return np.fromiter((cast(a, b)[2] is not None for a, b in zip(o, d)), dtype=bool, count=len(o))

    def first_hits(self, origins, directions):
        """(triangle, u, v) of each ray's nearest hit (-1, 0, 0 for none); ray_cast gives the
        point, whose barycentrics in its triangle are solved here."""
        o = np.asarray(origins, dtype=np.float32).tolist()
        d = np.asarray(directions, dtype=np.float32).tolist()
        cast = self._tree.ray_cast
        prims = np.full(len(o), -1, dtype=np.int32)
        points = np.zeros((len(o), 3))
        for i, (a, b) in enumerate(zip(o, d)):
            location, _normal, index, _distance = cast(a, b)
            if index is not None:
                prims[i] = index
                points[i] = location
        u = np.zeros(len(o), np.float32)
        v = np.zeros(len(o), np.float32)
        hit = prims >= 0
        if hit.any():
            verts, tris = self._corners
            corner = verts.astype(np.float64)[tris[prims[hit]]]  # (m, 3, 3)
            e1, e2, p = corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0], points[hit] - corner[:, 0]
            d11, d12, d22 = (np.einsum("ij,ij->i", a, b) for a, b in ((e1, e1), (e1, e2), (e2, e2)))
            p1, p2 = np.einsum("ij,ij->i", p, e1), np.einsum("ij,ij->i", p, e2)
            det = np.where(np.abs(d11 * d22 - d12 * d12) > 0, d11 * d22 - d12 * d12, 1.0)
            u[hit] = (d22 * p1 - d12 * p2) / det
            v[hit] = (d11 * p2 - d12 * p1) / det
        return prims, u, v
