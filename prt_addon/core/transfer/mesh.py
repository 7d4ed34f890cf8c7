"""Mesh geometry without Blender: quad triangulation, transforms, normal pairing, bake points.

The Blender readers (prt_addon.blender.scene.mesh_read) fill numpy arrays and call these functions.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..serial_blas import matmul_serial


def triangulate_quads(
    corner_verts: np.ndarray, starts: np.ndarray, sizes: np.ndarray, positions: npt.ArrayLike
) -> np.ndarray:
    """Vertex triangles of faces of 3 or 4 corners (triangle_corners, as vertex indices)."""
    return corner_verts[triangle_corners(corner_verts, starts, sizes, positions)]


def triangle_corners(
    corner_verts: np.ndarray, starts: np.ndarray, sizes: np.ndarray, positions: npt.ArrayLike
) -> np.ndarray:
    """Corner (loop) triangles of faces of 3 or 4 corners, as Blender's mesh tessellation
    (blenkernel mesh_tessellate.cc): a triangle is (0, 1, 2); a quad is (0, 1, 2), (0, 2, 3),
    or (0, 1, 3), (1, 2, 3) when the first split folds over (blenlib's
    is_quad_flip_v3_first_third_fast: (v2 - v1) x (v3 - v1) . (v4 - v1) x (v3 - v1) > 0,
    computed in float32 in the same order). A build of Blender that fuses multiply-adds (possible
    on arm64) can decide a quad whose test is within rounding of 0 the other way: either split
    covers that nearly flat quad."""
    per_face = sizes - 2
    first = np.cumsum(per_face) - per_face  # each face's first triangle
    corners = np.empty((int(per_face.sum()), 3), dtype=np.int32)
    tri = sizes == 3
    corners[first[tri]] = starts[tri, None] + np.array([0, 1, 2], dtype=np.int32)
    quad = ~tri
    if quad.any():
        quad_start, quad_first = starts[quad], first[quad]
        # Coordinates column by column (contiguous gathers; 12-byte rows gather element-wise).
        columns = np.ascontiguousarray(np.asarray(positions, dtype=np.float32).T)
        v = [[c[corner_verts[quad_start + i]] for c in columns] for i in range(4)]
        d12, d13, d14 = ([a - b for a, b in zip(v[i], v[0])] for i in (1, 2, 3))

        def cross(a, b):
            return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])

        with np.errstate(invalid="ignore", over="ignore"):  # non-finite positions: no flip
            ca, cb = cross(d12, d13), cross(d14, d13)
            flip = ((ca[0] * cb[0] + ca[1] * cb[1] + ca[2] * cb[2]) > np.float32(0.0)).view(np.int8)
        pair = np.empty((len(quad_start), 2, 3), dtype=np.int32)
        pair[:] = quad_start[:, None, None]
        pair += np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int32)
        pair[:, 0, 2] += flip  # (0, 1, 3)
        pair[:, 1, 0] += flip  # (1, 2, 3)
        if len(quad_start) == len(starts):  # quads only: the pairs are the triangles in order
            corners = pair.reshape(-1, 3)
        else:
            corners[quad_first] = pair[:, 0]
            corners[quad_first + 1] = pair[:, 1]
    return corners


def matrix_to_numpy(matrix: Iterable[Iterable[float]]) -> np.ndarray:
    return np.array([list(row) for row in matrix], dtype=np.float64)


def transform_points(matrix4: npt.ArrayLike, points: npt.ArrayLike) -> np.ndarray:
    m = np.asarray(matrix4, dtype=np.float64)
    return matmul_serial(np.asarray(points, dtype=np.float64), m[:3, :3].T) + m[:3, 3]


def transform_normals(matrix4: npt.ArrayLike, normals: npt.ArrayLike) -> np.ndarray:
    """Normals under the inverse transpose of the linear part, renormalised (0 stays 0)."""
    linear = np.asarray(matrix4, dtype=np.float64)[:3, :3]
    # inv(linear)^T = cofactor matrix / det (rows: cross products of the rows); the normals are
    # renormalised, so only det's sign matters. Not np.linalg.inv, whose LAPACK call leaves an
    # OpenBLAS thread spinning (core.serial_blas).
    cofactor = np.cross(linear[[1, 2, 0]], linear[[2, 0, 1]])
    det = float(np.dot(linear[0], cofactor[0]))
    normal_matrix = cofactor * np.sign(det) if det != 0.0 and np.isfinite(det) else linear
    n = matmul_serial(np.asarray(normals, dtype=np.float64), normal_matrix.T)
    length = np.sqrt(np.einsum("ij,ij->i", n, n))[:, None]
    return np.divide(n, length, out=np.zeros_like(n), where=length > 1e-30)


@dataclass
class BakePoints:
    """Where the transfer is evaluated: P unique (position, normal) pairs in world space.

    `scatter` maps each element of the attribute domain (vertex or corner) to its point; for the
    POINT domain it is None (points are the vertices, in order). `vertex` is each point's vertex
    (None for the POINT domain: point i is vertex i).
    """

    domain: str
    positions: np.ndarray  # (P, 3) float64 world
    normals: np.ndarray  # (P, 3) float64 world, unit (or 0)
    scatter: object  # None or (E,) int64
    vertex: object = None  # None or (P,) int64


def vertex_points(matrix4: npt.ArrayLike, positions: npt.ArrayLike, normals: npt.ArrayLike) -> BakePoints:
    """POINT-domain BakePoints: one point per vertex, in order."""
    return BakePoints("POINT", transform_points(matrix4, positions), transform_normals(matrix4, normals), None)


# Corner normals of one vertex that differ by at most this much in every component count as
# one normal: a flat grid's faces get normals of (0, 0, 1) and (0, 0, 0.99999994) from rounding,
# which would otherwise split its vertices into corners. The transfer changes by ~1e-6.
NORMAL_TOLERANCE = 1e-6


def vertex_normal_pairs(
    corner_verts: np.ndarray, corner_normals: npt.ArrayLike, vertex_count: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The unique (vertex, normal) pairs of a mesh's corners: (vertex index, normal, inverse),
    sorted by vertex, with inverse mapping each corner to its pair. Corner normals within
    NORMAL_TOLERANCE of their vertex's reference normal (one of its corners') are that normal."""
    corner_normals = np.asarray(corner_normals, dtype=np.float32).reshape(-1, 3)
    reference = np.zeros((vertex_count, 3), dtype=np.float32)
    reference[corner_verts] = corner_normals  # one of the vertex's corners (the last written)
    at_reference = reference[corner_verts]
    close = np.ones(len(corner_verts), dtype=bool)
    for axis in range(3):  # (column by column: faster than a reduction along axis 1)
        close &= np.abs(corner_normals[:, axis] - at_reference[:, axis]) <= NORMAL_TOLERANCE
    if close.all():
        has_corner = np.zeros(vertex_count, dtype=bool)
        has_corner[corner_verts] = True
        vert = np.flatnonzero(has_corner)
        position = np.cumsum(has_corner) - 1
        return vert, reference[vert], position[corner_verts]
    snapped = np.where(close[:, None], at_reference, corner_normals)
    bits = np.ascontiguousarray(snapped).view(np.int32)
    # np.unique(rows, axis=0, return_inverse=True), computed with a lexsort of the int32 columns
    # (same order, same result; np.unique sorts the rows as structured items, ~5 times slower).
    order = np.lexsort((bits[:, 2], bits[:, 1], bits[:, 0], corner_verts))
    ordered_vert, ordered_bits = corner_verts[order], bits[order]
    new = np.empty(len(order), dtype=bool)
    new[:1] = True
    new[1:] = ordered_vert[1:] != ordered_vert[:-1]
    for axis in range(3):
        new[1:] |= ordered_bits[1:, axis] != ordered_bits[:-1, axis]
    inverse = np.empty(len(order), dtype=np.intp)
    inverse[order] = np.cumsum(new) - 1
    return ordered_vert[new], ordered_bits[new].view(np.float32), inverse


def concatenate_parts(parts: Sequence[tuple[object, np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    if not parts:
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32)
    offsets = np.cumsum([0] + [len(v) for _o, v, _t in parts[:-1]])
    vertices = np.concatenate([v for _o, v, _t in parts])
    triangles = np.concatenate([t + np.int32(off) for (_o, _v, t), off in zip(parts, offsets)])
    return vertices, triangles


def unit_normals(normals: npt.ArrayLike) -> np.ndarray:
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    length = np.sqrt(np.einsum("ij,ij->i", n, n))  # (np.linalg.norm(axis=1) is ~4 times slower)
    ok = np.isfinite(length) & (length > 1e-12)
    return np.divide(n, length[:, None], out=np.zeros_like(n), where=ok[:, None])
