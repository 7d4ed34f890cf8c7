"""Hits on texel-baked meshes as texel nodes: hit triangle and barycentrics -> UV -> the texel under it.

In an interreflected texel bake the covered texels of a lightmap are the bounce nodes of their
mesh (core.transfer.bounce): a blocked ray that meets a texel-baked triangle at barycentrics
(u, v) reads t^b at its UV point p = a + u (b - a) + v (c - a) (a, b, c the triangle's UVs), from
the texel (floor(R p_u), floor(R p_v)) holding p. Where that texel is not covered (its centre
lies outside the chart: the chart's border), the nearest covered texel within REACH texels
stands in, so a hit on the mesh always finds a node of its own chart.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

# Texels (Chebyshev distance) a border texel may borrow its node from.
REACH = 2

# Neighbour offsets (drow, dcol) in the order a border texel picks them: edges first, then corners.
_NEIGHBOURS = ((0, -1), (0, 1), (-1, 0), (1, 0), (-1, -1), (-1, 1), (1, -1), (1, 1))


def node_lookup(texels: npt.ArrayLike, resolution: int, reach: int = REACH) -> np.ndarray:
    """(res * res,) int32: the node (index into `texels`, the sorted covered texels row * res +
    col) of each texel, the covered ones their own, others within `reach` rounds of 8-neighbour
    growth that of a neighbour (edges before corners), else -1."""
    res = int(resolution)
    lookup = np.full((res + 2, res + 2), -1, dtype=np.int32)  # (a border of -1 on every side)
    flat = np.asarray(texels, dtype=np.int64)
    lookup[1 + flat // res, 1 + flat % res] = np.arange(len(flat), dtype=np.int32)
    inner = lookup[1:-1, 1:-1]
    for _round in range(int(reach)):
        empty = inner < 0
        if not empty.any():
            break
        grown = inner.copy()
        for dr, dc in _NEIGHBOURS:
            neighbour = lookup[1 + dr : res + 1 + dr, 1 + dc : res + 1 + dc]
            take = (grown < 0) & empty & (neighbour >= 0)
            grown[take] = neighbour[take]
        inner[...] = grown
    return np.ascontiguousarray(inner).reshape(-1)


class TexelNodes:
    """The texel nodes of one texel-baked mesh: uvs (T, 3, 2) per triangle, in the triangle order
    of the hits that reach it; texels (P,) its covered texels (core.transfer.texels.TexelSamples)."""

    def __init__(self, uvs: npt.ArrayLike, texels: npt.ArrayLike, resolution: int, reach: int = REACH) -> None:
        uv = np.asarray(uvs, dtype=np.float64).reshape(-1, 3, 2)
        self.resolution = int(resolution)
        self.count = len(np.asarray(texels))
        self.triangles = len(uv)
        self.origin = uv[:, 0]
        self.edges = np.stack([uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]], axis=1)  # (T, 2, 2)
        self.lookup = node_lookup(texels, self.resolution, reach)

    def nodes(self, triangles: npt.ArrayLike, u: npt.ArrayLike, v: npt.ArrayLike) -> np.ndarray:
        """(m,) int32 node of each hit on triangle `triangles[j]` (local) at barycentrics (u, v)
        (weights of corners 1 and 2), -1 where its UV point has no covered texel near it."""
        tri = np.asarray(triangles, dtype=np.intp)
        u = np.asarray(u, dtype=np.float64)[:, None]
        v = np.asarray(v, dtype=np.float64)[:, None]
        p = self.origin[tri] + u * self.edges[tri, 0] + v * self.edges[tri, 1]
        res = self.resolution
        with np.errstate(invalid="ignore"):
            cell = np.floor(p * res)
            inside = np.all((cell >= 0) & (cell < res), axis=1)
        cell = np.where(inside[:, None], cell, 0).astype(np.int64)
        out = self.lookup[cell[:, 1] * res + cell[:, 0]]
        return np.where(inside, out, np.int32(-1)).astype(np.int32)


class TexelRemap:
    """The texel nodes of every texel-baked part of an occluder's triangle soup, for a HitTransport
    (its `remap`): add() each part's triangle range and first node; a call gives the hits on
    those triangles their texel nodes."""

    def __init__(self) -> None:
        self.parts: list[tuple[int, int, TexelNodes]] = []  # (first triangle, first node, nodes)

    def add(self, first_triangle: int, first_node: int, nodes: TexelNodes) -> None:
        self.parts.append((int(first_triangle), int(first_node), nodes))

    def __call__(
        self, prims: np.ndarray, ud: np.ndarray, vd: np.ndarray, det: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """(which, nodes): the hits (indices into prims) on texel-baked triangles and their global
        node (-1: none), from the hits' (u det, v det, det) (core.transfer.bounce_hits); None when
        no hit is on one."""
        prims = np.asarray(prims)
        picked, found = [], []
        for first, node0, texel_nodes in self.parts:
            which = np.flatnonzero((prims >= first) & (prims < first + texel_nodes.triangles))
            if not len(which):
                continue
            d = det[which].astype(np.float64)
            with np.errstate(divide="ignore", invalid="ignore"):
                u, v = ud[which] / d, vd[which] / d  # (det <= 0: a back face, dropped by the sink)
            local = texel_nodes.nodes(prims[which] - first, u, v)
            picked.append(which)
            found.append(np.where(local >= 0, local + np.int32(node0), np.int32(-1)).astype(np.int32))
        if not picked:
            return None
        return np.concatenate(picked), np.concatenate(found)
