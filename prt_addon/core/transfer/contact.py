"""Surfaces in contact: the tangent that moves a ray origin into its point's own surface.

Where another surface touches (a box standing on the ground), a point's origin offset along its
normal alone lies in that surface's plane and its rays slip under it; moved also along this
tangent, into its own faces, the origin lies on the side where its own surface is (docs/bake.md,
"Contacts").
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from .mesh import unit_normals

# inward_tangents: a fan whose mean direction s has at least this tangential length is one-sided
# (a boundary, or a crease between differently shaded faces) and gets a unit tangent; a nearly
# balanced fan (an interior vertex) gets a proportionally shorter one.
FAN_ONE_SIDED = 0.25


FAN_BLOCK = 1 << 16  # triangles per block (working memory ~10 MB)


# Weight of a fan corner: (n_face . n_point)^FACE_POWER, clamped at 0: the corners of the face(s)
# a point's normal comes from dominate (a flat-shaded box's side point ignores the bottom face).
FACE_POWER_SQUARINGS = 3


FACE_POWER = 2**FACE_POWER_SQUARINGS


def inward_tangents(
    positions: npt.ArrayLike,
    normals: npt.ArrayLike,
    vertices: npt.ArrayLike,
    triangles: npt.ArrayLike,
    point_vertex: npt.ArrayLike | None = None,
) -> np.ndarray:
    """(P, 3) tangents, of length at most 1, pointing from each point into its own surface.

    For the point's vertex a and each triangle corner (a, b, c) around it, with unit edges e1,
    e2 along b - a and c - a, corner angle alpha and unit face normal m, the fan's mean
    direction is

        s = sum w int_corner u(theta) dtheta / sum w alpha,   w = max(0, m . n)^FACE_POWER,

    the integral of the unit vector u over the corner's angle being 2 sin(alpha / 2) times its
    bisector, |e1 - e2| (e1 + e2) / |e1 + e2|: for a flat fan s does not depend on how it is
    triangulated (0 for a full disc, 2 / pi up a straight boundary). Its tangential part s_t =
    s - (s . n) n points into the surface at a boundary (the foot of a wall: up the wall) or at
    a crease (a flat box's side point: up the side, not into the bottom face) and is ~0 at an
    interior vertex; the result is s_t / max(|s_t|, FAN_ONE_SIDED).
    """
    n = unit_normals(normals)
    count = len(n)
    if len(np.asarray(positions).reshape(-1, 3)) != count:
        raise ValueError("positions and normals must have the same length")
    v = np.asarray(vertices, dtype=np.float32).reshape(-1, 3)
    t = np.asarray(triangles).reshape(-1, 3)
    if len(t) and (t.min() < 0 or t.max() >= len(v)):
        raise ValueError("triangle indices out of range")
    if point_vertex is None:
        if count > len(v):
            raise ValueError("more points than vertices: give point_vertex")
        by_vertex = None
    else:
        pv = np.asarray(point_vertex, dtype=np.int64).ravel()
        if len(pv) != count:
            raise ValueError("point_vertex must give one vertex per point")
        if count and (pv.min() < 0 or pv.max() >= len(v)):
            raise ValueError("point_vertex out of range")
        # The points of each vertex, grouped: vertex a has points by_vertex[first[a]:][:k[a]].
        k = np.bincount(pv, minlength=len(v))
        by_vertex = np.argsort(pv, kind="stable")
        first = np.cumsum(k) - k
    out = np.zeros((count, 3))
    if count == 0 or len(t) == 0:
        return out
    # Component by component (1-D float32 arrays): numpy gathers and reduces (n, 3) rows several
    # times slower.
    vc = [np.ascontiguousarray(v[:, i]) for i in range(3)]
    nc = [n[:, i].astype(np.float32) for i in range(3)]
    sums = np.zeros((4, count))  # sum w alpha, then sum w int u dtheta
    for t0 in range(0, len(t), FAN_BLOCK):
        tri = [np.ascontiguousarray(t[t0 : t0 + FAN_BLOCK, j]) for j in range(3)]
        x = [[c[i] for c in vc] for i in tri]  # x[j][axis]: corner j of each triangle
        # Unit edges e[j] = x[j + 1] - x[j], and unit face normals.
        e = []
        for j in range(3):
            ej = [x[(j + 1) % 3][i] - x[j][i] for i in range(3)]
            length = np.sqrt(ej[0] * ej[0] + ej[1] * ej[1] + ej[2] * ej[2])
            np.maximum(length, 1e-30, out=length)
            e.append([c / length for c in ej])
        m = [
            e[0][1] * e[1][2] - e[0][2] * e[1][1],
            e[0][2] * e[1][0] - e[0][0] * e[1][2],
            e[0][0] * e[1][1] - e[0][1] * e[1][0],
        ]
        length = np.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2])
        np.maximum(length, 1e-30, out=length)
        m = [c / length for c in m]
        for j in range(3):  # corner j: e1 = e[j] (to the next corner), e2 = -e[j - 1]
            e1, e2 = e[j], e[j - 1]
            cos = -(e1[0] * e2[0] + e1[1] * e2[1] + e1[2] * e2[2])
            np.clip(cos, -1.0, 1.0, out=cos)
            half = [e1[i] - e2[i] for i in range(3)]  # |.| = 2 cos(alpha / 2)
            # int_corner u dtheta = 2 sin(alpha / 2) half / |half| = tan(alpha / 2) half.
            tan = np.sqrt(np.divide(1.0 - cos, 1.0 + cos, out=np.zeros_like(cos), where=cos > -1))
            a = tri[j]
            if by_vertex is None:
                point = a
                if count < len(v):
                    keep = np.flatnonzero(a < count)
                    point, cos, tan = a[keep], cos[keep], tan[keep]
                    mj, half = [c[keep] for c in m], [c[keep] for c in half]
                else:
                    mj = m
            else:
                per = k[a]
                pair = np.repeat(np.arange(len(a)), per)  # one (corner, point) pair per point
                rank = np.arange(len(pair)) - np.repeat(np.cumsum(per) - per, per)
                point = by_vertex[first[a[pair]] + rank]
                cos, tan = cos[pair], tan[pair]
                mj, half = [c[pair] for c in m], [c[pair] for c in half]
            if len(point) == 0:
                continue
            w = mj[0] * nc[0][point] + mj[1] * nc[1][point] + mj[2] * nc[2][point]
            np.maximum(w, 0.0, out=w)
            for _ in range(FACE_POWER_SQUARINGS):
                w *= w
            weights = [w * np.arccos(cos)]
            w *= tan
            weights += [w * c for c in half]
            # Accumulate over the range of points touched (mesh order keeps it short).
            lo, hi = int(point.min()), int(point.max()) + 1
            local = point - lo
            for i, weight in enumerate(weights):
                sums[i, lo:hi] += np.bincount(local, weights=weight, minlength=hi - lo)
    total = sums[0]
    np.divide(sums[1:].T, total[:, None], out=out, where=total[:, None] > 0)
    out -= np.einsum("ij,ij->i", out, n)[:, None] * n
    length = np.sqrt(np.einsum("ij,ij->i", out, out))
    out /= np.maximum(length, FAN_ONE_SIDED)[:, None]
    return out


def under_other_surfaces(
    positions: npt.ArrayLike,
    normals: npt.ArrayLike,
    offset: float,
    occluder: Any,
    vertices: npt.ArrayLike,
    triangles: npt.ArrayLike,
) -> np.ndarray:
    """(P,) bool: whether another surface lies on the point within `offset` of its own plane, facing
    it (a box's bottom face on the floor): from the ray origin x + offset n, back along -n, the
    nearest of the other surfaces' triangles (`occluder` of `vertices`, `triangles`) is hit within
    2 offset, on a triangle facing the point. Rays offset along n would start under that surface
    and see through it; Cycles, which skips only a ray's own triangle, sees the surface there."""
    x = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    out = np.zeros(len(x), dtype=bool)
    if occluder is None or len(x) == 0:
        return out
    origins = x + offset * n
    prims = np.asarray(occluder.nearest_triangles(origins.astype(np.float32), (-n).astype(np.float32)))
    hit = np.flatnonzero(prims >= 0)
    if len(hit) == 0:
        return out
    corners = np.asarray(vertices, dtype=np.float64)[np.asarray(triangles)[prims[hit]]]
    plane = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    along = -np.einsum("ij,ij->i", n[hit], plane)
    with np.errstate(divide="ignore", invalid="ignore"):
        distance = np.einsum("ij,ij->i", corners[:, 0] - origins[hit], plane) / along
    facing = np.einsum("ij,ij->i", n[hit], plane) < 0.0  # (a coplanar surface facing the same way is no cover)
    out[hit] = facing & np.isfinite(distance) & (distance <= 2.0 * offset)
    return out
