"""PROTOTYPE stand-in for the texel rasteriser (replaced by the real module)."""

from dataclasses import dataclass

import numpy as np

SAMPLE_OFFSETS = np.array([[0.375, 0.125], [0.875, 0.375], [0.625, 0.875], [0.125, 0.625]])


@dataclass
class TexelSamples:
    resolution: int
    texels: np.ndarray
    triangles: np.ndarray
    barycentrics: np.ndarray
    positions: np.ndarray
    normals: np.ndarray
    overlapping: int = 0
    outside: int = 0
    degenerate: int = 0


def texel_samples(uvs, positions, normals, resolution, offsets=SAMPLE_OFFSETS, inset=0.0):
    uvs = np.asarray(uvs, np.float64) * resolution
    res = resolution
    S = len(offsets)
    found = {}
    for t in range(len(uvs)):
        a, b, c = uvs[t]
        det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
        if abs(det) < 1e-12:
            continue
        lo = np.floor(uvs[t].min(axis=0)).astype(int).clip(0, res - 1)
        hi = np.floor(uvs[t].max(axis=0)).astype(int).clip(0, res - 1)
        cols, rows = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1))
        cols, rows = cols.ravel(), rows.ravel()
        for s, (ox, oy) in enumerate(offsets):
            px, py = cols + ox, rows + oy
            w1 = ((px - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (py - a[1])) / det
            w2 = ((b[0] - a[0]) * (py - a[1]) - (px - a[0]) * (b[1] - a[1])) / det
            w0 = 1 - w1 - w2
            inside = (w0 >= 0) & (w1 >= 0) & (w2 >= 0)
            for i in np.flatnonzero(inside):
                key = rows[i] * res + cols[i]
                found.setdefault(key, {}).setdefault(s, (t, (w0[i], w1[i], w2[i])))
    keys = np.array(sorted(found), dtype=np.int64)
    tri = np.zeros((S, len(keys)), np.int64)
    bary = np.zeros((S, len(keys), 3))
    for j, k in enumerate(keys):
        d = found[k]
        first = next(iter(d.values()))
        for s in range(S):
            t, w = d.get(s, first)
            tri[s, j] = t
            bary[s, j] = w
    pos = np.einsum("spk,spkd->spd", bary, np.asarray(positions)[tri])
    nrm = np.einsum("spk,spkd->spd", bary, np.asarray(normals)[tri])
    nrm /= np.maximum(np.linalg.norm(nrm, axis=2, keepdims=True), 1e-30)
    return TexelSamples(res, keys, tri, bary, pos, nrm)
