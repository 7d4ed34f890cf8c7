"""Occluders for the transfer bake: the Embree backend and the "nothing can occlude" tests.

Every occluder implements core.trace.occluders.Occluder (the Blender layer's BVH-tree occluder
too). A ray is occluded when it hits any triangle at a distance in (0, inf). The caller offsets the
origins (Embree's tnear is fixed at 0). occluded() must be thread-safe.

Culling (no rays where nothing can occlude), used by prt_addon.core.transfer.quadrature:

* `cannot_self_occlude(vertices, triangles)`: True when the mesh is planar, or closed and convex.
  A ray leaving a point x of a convex body K with n . w > 0, where n lies in the normal cone of K
  at x (a face normal, or an angle-weighted average of the face normals around a convex vertex,
  which is what Blender's vertex normals are), stays in the open half-space {(z - x) . n > 0}
  that contains no point of K. A planar mesh is the degenerate case. This does not hold for
  custom normals, so the caller must not use it then.
* `box_can_occlude(points, normals, boxes)`: an axis-aligned box can only occlude rays above the
  tangent plane of (x, n) if part of it lies above that plane: max over the box of (z - x) . n =
  (c - x) . n + h . |n| > 0, with c the centre and h the half extents.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..serial_blas import matmul_serial
from . import embree_buffers

try:  # the wheel exists for x86_64 Linux/Windows and macOS only
    from embreex import mesh_construction as _embree_mesh, rtcore_scene as _embree_scene

    EMBREE_AVAILABLE = True
    EMBREE_IMPORT_ERROR = ""
except (ImportError, OSError) as exc:  # pragma: no cover - depends on the platform
    _embree_mesh = _embree_scene = None
    EMBREE_AVAILABLE = False
    EMBREE_IMPORT_ERROR = f"{type(exc).__name__}: {exc}"


def as_triangles(vertices: npt.ArrayLike, triangles: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """(V, 3) float32 C-contiguous vertices and (T, 3) int32 triangles, validated."""
    v = np.ascontiguousarray(vertices, dtype=np.float32).reshape(-1, 3)
    t = np.ascontiguousarray(triangles, dtype=np.int32).reshape(-1, 3)
    if len(t) and (t.min() < 0 or t.max() >= len(v)):
        raise ValueError("triangle indices out of range")
    if not np.all(np.isfinite(v)):
        raise ValueError("occluder vertices must be finite")
    return v, t


class EmbreeOccluder:
    """Occlusion queries against a static triangle soup with embreex (Embree 4).

    embreex's run() traces one ray at a time in one thread but releases the GIL, so several
    Python threads calling occluded() on disjoint batches scale with the cores. The BVH is built
    on the first run(): the constructor does it with one ray so that later calls are read-only.
    Embree reads the triangles in place where `embree_buffers` works (`geometry` "SHARED"),
    else they are copied by embreex's TriangleMesh ("COPIED"); the two trace identically.
    """

    name = "EMBREE"
    max_threads = 16

    def __init__(
        self, vertices: npt.ArrayLike, triangles: npt.ArrayLike, robust: bool = False, shared: bool = True
    ) -> None:
        if not EMBREE_AVAILABLE:
            raise RuntimeError(f"embreex is not available ({EMBREE_IMPORT_ERROR})")
        v, t = as_triangles(vertices, triangles)
        if len(t) == 0:
            raise ValueError("an occluder needs at least one triangle")
        self.triangle_count = len(t)
        self._scene = _embree_scene.EmbreeScene(robust=robust)
        self.geometry = "COPIED"
        if shared and embree_buffers.available():
            try:
                self._buffers = embree_buffers.attach_triangles(self._scene, v, t)
                self.geometry = "SHARED"
            except RuntimeError:  # an Embree error: copy instead, into a scene not touched yet
                self._scene = _embree_scene.EmbreeScene(robust=robust)
        if self.geometry == "COPIED":
            self._mesh = _embree_mesh.TriangleMesh(self._scene, v, t)
        self._scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32), query="OCCLUDED")

    def occluded(self, origins: npt.ArrayLike, directions: npt.ArrayLike) -> np.ndarray:
        # run() reads strided (N, 3) float32 views as fast as contiguous arrays (measured): the
        # bake passes views of 16-byte rows, which must not be copied here.
        o = np.asarray(origins, dtype=np.float32)
        d = np.asarray(directions, dtype=np.float32)
        if len(o) == 0:
            return np.zeros(0, dtype=bool)
        # run() returns int32: 0 where occluded, -1 where the ray is free.
        return self._scene.run(o, d, query="OCCLUDED") == 0

    def nearest_triangles(self, origins: npt.ArrayLike, directions: npt.ArrayLike) -> np.ndarray:
        # The primitive alone: embreex's full output (barycentrics, distance, normal) costs ~1.4
        # times as much with two threads; core.transfer.bounce solves the barycentrics of the hits it keeps.
        o = np.asarray(origins, dtype=np.float32)
        d = np.asarray(directions, dtype=np.float32)
        if len(o) == 0:
            return np.zeros(0, np.int32)
        return self._scene.run(o, d, query="INTERSECT")


def bounding_box(vertices: npt.ArrayLike) -> np.ndarray:
    """(2, 3) float64 [min, max] of (V, 3) points."""
    v = np.asarray(vertices).reshape(-1, 3)
    # Column by column: numpy reduces an (n, 3) array along axis 0 about 20 times slower.
    return np.array([[v[:, i].min() for i in range(3)], [v[:, i].max() for i in range(3)]], dtype=np.float64)


def box_can_occlude(points: np.ndarray, normals: npt.ArrayLike, boxes: npt.ArrayLike) -> np.ndarray:
    """(P,) bool: does any of the (K, 2, 3) boxes reach above the tangent plane of each point."""
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 2, 3)
    if len(boxes) == 0:
        return np.zeros(len(points), dtype=bool)
    p = np.asarray(points, dtype=np.float64)
    n = np.asarray(normals, dtype=np.float64)
    centre = 0.5 * (boxes[:, 0] + boxes[:, 1])
    half = 0.5 * (boxes[:, 1] - boxes[:, 0])
    height = matmul_serial(n, centre.T) + matmul_serial(np.abs(n), half.T) - np.einsum("ij,ij->i", p, n)[:, None]
    return (height > 0.0).any(axis=1)


def _triangle_normals(v, t):
    return np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])


def _used_vertices(t, count):
    """Sorted unique vertex indices of the (non-empty) triangles t (np.unique(t), without its sort)."""
    mask = np.zeros(max(count, int(t.max()) + 1), dtype=bool)
    mask[t.ravel()] = True
    return np.flatnonzero(mask)


def is_planar(vertices: npt.ArrayLike, triangles: npt.ArrayLike, rel_tol: float = 1e-6) -> bool:
    """True when every vertex of the triangles lies within rel_tol * (bounding-box diagonal) of
    their least-squares plane, whose normal is the eigenvector of the smallest eigenvalue of the
    vertices' scatter matrix (a 3 x 3 problem: no per-triangle work)."""
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if len(t) == 0:
        return False
    used = v[_used_vertices(t, len(v))]
    lower, upper = bounding_box(used)
    scale = np.linalg.norm(upper - lower)
    if scale == 0.0:
        return False
    centred = used - np.array([used[:, i].mean() for i in range(3)])
    # (einsum and matmul_serial: no threaded BLAS, see core.serial_blas)
    normal = np.linalg.eigh(np.einsum("ij,ik->jk", centred, centred))[1][:, 0]
    return bool(np.abs(matmul_serial(centred, normal)).max() <= rel_tol * scale)


def is_closed_convex(vertices: npt.ArrayLike, triangles: npt.ArrayLike, rel_tol: float = 1e-6) -> bool:
    """True when the triangles form one closed, consistently oriented, convex surface.

    Checks: every edge is shared by exactly two triangles with opposite orientations; every edge
    is convex (the far vertex of each neighbour lies on or behind the triangle's plane); the
    Euler characteristic V - E + F is 2 (one sphere-like piece); the corner angles around every
    vertex sum to at most 2 pi. A closed connected surface that is locally convex everywhere
    bounds a convex body (Gauss-Bonnet fixes the degree of its Gauss map to 1).
    """
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if len(t) < 4:
        return False
    used = _used_vertices(t, len(v))
    # Euler test with E = 3 F / 2 (each edge of a closed surface has two half-edges, which is
    # checked below): cheap, so done first, as most meshes fail it.
    if len(used) - (3 * len(t)) // 2 + len(t) != 2:
        return False
    lower, upper = bounding_box(v[used])
    scale = np.linalg.norm(upper - lower)
    if scale == 0.0:
        return False
    tol = rel_tol * scale
    # Directed half-edges (a -> b) of every triangle, with the opposite vertex.
    a = t.ravel()
    b = t[:, [1, 2, 0]].ravel()
    opposite = t[:, [2, 0, 1]].ravel()
    face = np.repeat(np.arange(len(t)), 3)
    n_vert = int(t.max()) + 1
    key = a * n_vert + b
    twin_key = b * n_vert + a
    order = np.argsort(key)
    sorted_key = key[order]
    if np.any(sorted_key[1:] == sorted_key[:-1]):
        return False  # a directed edge used twice: non-manifold or inconsistent orientation
    pos = np.searchsorted(sorted_key, twin_key)
    pos = np.minimum(pos, len(sorted_key) - 1)
    if not np.all(sorted_key[pos] == twin_key):
        return False  # a boundary edge: not closed
    twin = order[pos]
    normals = _triangle_normals(v, t)
    lengths = np.linalg.norm(normals, axis=1)
    unit = normals / np.where(lengths > 0, lengths, 1.0)[:, None]
    # Far vertex of the neighbouring triangle against this triangle's plane.
    height = np.einsum("ij,ij->i", v[opposite[twin]] - v[a], unit[face])
    if np.any(height > tol):
        return False
    # Corner angles.
    e1 = v[b] - v[a]
    e2 = v[opposite] - v[a]
    cos = np.einsum("ij,ij->i", e1, e2) / np.maximum(np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1), 1e-300)
    angles = np.arccos(np.clip(cos, -1.0, 1.0))
    angle_sum = np.bincount(a, weights=angles, minlength=n_vert)[used]
    return bool(np.all(angle_sum <= 2.0 * np.pi + 1e-6))


def cannot_self_occlude(vertices: npt.ArrayLike, triangles: npt.ArrayLike) -> bool:
    """True when no ray above a surface point's tangent plane can hit this same mesh."""
    return is_planar(vertices, triangles) or is_closed_convex(vertices, triangles)
