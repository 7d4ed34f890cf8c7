"""The occluder builders: Embree (core.trace.raytrace) and the fallback on mathutils.bvhtree.BVHTree.

ray_cast() holds the GIL and is called once per ray from Python, so this backend is single
threaded (max_threads = 1) and much slower than Embree (measured in docs/bake.md); it exists for platforms
without an embreex wheel (Linux and Windows on ARM).
"""

import numpy as np
from mathutils.bvhtree import BVHTree

from ...core.trace import raytrace
from ...core.trace.raytrace import as_triangles


class BVHTreeOccluder:
    name = "BVHTREE"
    max_threads = 1

    def __init__(self, vertices, triangles):
        v, t = as_triangles(vertices, triangles)
        if len(t) == 0:
            raise ValueError("an occluder needs at least one triangle")
        self.triangle_count = len(t)
        self._tree = BVHTree.FromPolygons(v.tolist(), t.tolist(), all_triangles=True, epsilon=0.0)

    def occluded(self, origins, directions):
        o = np.asarray(origins, dtype=np.float32).tolist()
        d = np.asarray(directions, dtype=np.float32).tolist()
        cast = self._tree.ray_cast
        return np.fromiter((cast(a, b)[2] is not None for a, b in zip(o, d)), dtype=bool, count=len(o))

    def nearest_triangles(self, origins, directions):
        """The triangle of each ray's nearest hit (-1 for none)."""
        o = np.asarray(origins, dtype=np.float32).tolist()
        d = np.asarray(directions, dtype=np.float32).tolist()
        cast = self._tree.ray_cast
        indices = (cast(a, b)[2] for a, b in zip(o, d))
        return np.fromiter((-1 if i is None else i for i in indices), dtype=np.int32, count=len(o))


# The ray-tracing backends, injected into the core's lazily built occluder.
BUILDERS = {"EMBREE": raytrace.EmbreeOccluder, "BVHTREE": BVHTreeOccluder}


def auto_backend():
    """The backend Auto picks: Embree where its wheel imports, else the BVH tree."""
    return "EMBREE" if raytrace.EMBREE_AVAILABLE else "BVHTREE"
