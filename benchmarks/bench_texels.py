"""Texel benchmark: texel_samples on a one-quad 2048x2048 map and on 20k-triangle meshes at 512.

Run: .venv/bin/python benchmarks/bench_texels.py
Prints wall and CPU seconds (best of a few runs: other work on the machine inflates both) and the
post-processing of a 512x512 map (dilate, seam_pairs, fix_seams).
"""

import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from prt_addon.core.transfer import lightmap
from prt_addon.core.transfer.texels import texel_samples


def best(fn, repeats=3):
    walls, cpus = [], []
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        result = fn()
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
    return min(walls), min(cpus), result


def quad():
    uv = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], float)
    pos = np.concatenate([uv, np.zeros((2, 3, 1))], axis=2)
    return uv, pos, np.tile([0.0, 0.0, 1.0], (2, 3, 1))


def grid(quads_per_side, islands):
    """A wavy grid of 2 quads_per_side^2 triangles and its corner vertices; UVs one island
    (islands=False) or one island per quad packed in cells with a margin (islands=True: nearly
    every texel is an edge texel, every inner edge a seam)."""
    n = quads_per_side
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    corners = np.stack(
        [np.stack([i, j], -1), np.stack([i + 1, j], -1), np.stack([i + 1, j + 1], -1), np.stack([i, j + 1], -1)], 2
    )
    corners = corners.reshape(-1, 4, 2).astype(float)
    tris = corners[:, [[0, 1, 2], [0, 2, 3]]].reshape(-1, 3, 2)  # (2 n^2, 3, 2) grid coordinates
    s = tris / n
    pos = np.concatenate([s, 0.05 * np.sin(6 * s[..., :1]) * np.cos(5 * s[..., 1:])], axis=2)
    nrm = np.tile([0.0, 0.0, 1.0], (len(tris), 3, 1))
    vertex = (tris[..., 0] * (n + 1) + tris[..., 1]).astype(np.int64)
    if not islands:
        return s, pos, nrm, vertex
    if islands == "quarters":  # four islands: the grid cut along its two middle lines
        quarter = np.repeat((corners[:, 0] >= n // 2).astype(float), 2, axis=0)  # (2 n^2, 2)
        uv = 0.02 + 0.48 * quarter[:, None, :] + 0.46 * (s - 0.5 * quarter[:, None, :]) * 2
        return uv, pos, nrm, vertex
    cell = np.repeat(corners[:, 0], 2, axis=0)  # each quad's own cell
    uv = (cell[:, None, :] + 0.2 + 0.6 * (tris - cell[:, None, :])) / n
    return uv, pos, nrm, vertex


def main():
    for name, (uv, pos, nrm, _v), res in (
        ("one quad", quad() + (None,), 2048),
        ("20k triangles, one island", grid(100, False), 512),
        ("20k triangles, 10k islands", grid(100, True), 512),
    ):
        wall, cpu, s = best(lambda: texel_samples(uv, pos, nrm, res))
        print(f"texel_samples {name:28s} {res}x{res}: {s.count:8d} texels  {wall:6.2f} s wall  {cpu:6.2f} s CPU")
    # The 2048 map's 1.3 GB result is mostly fresh memory: numpy asks for transparent huge pages
    # (madvise), whose allocation (compaction) can cost more than the work; the same without.
    uv, pos, nrm = quad()
    advice = np.core.multiarray._set_madvise_hugepage(False)
    wall, cpu, s = best(lambda: texel_samples(uv, pos, nrm, 2048))
    np.core.multiarray._set_madvise_hugepage(advice)
    print(f"texel_samples one quad, numpy's huge-page advice off, 2048x2048: {wall:6.2f} s wall  {cpu:6.2f} s CPU")
    del s
    uv, pos, nrm, vertex = grid(100, True)
    s = texel_samples(uv, pos, nrm, 512)
    image = s.image(np.concatenate([s.positions.mean(axis=0), s.normals.mean(axis=0)], axis=1))  # 6 channels
    covered = s.covered()
    wall, cpu, _ = best(lambda: lightmap.dilate(image, covered, passes=4))
    print(f"dilate 512x512x6 islands, 4 passes + nearest: {wall:6.3f} s wall  {cpu:6.3f} s CPU")
    rows, cols = np.indices((2048, 2048))
    disc = (rows - 1000.5) ** 2 + (cols - 1100.5) ** 2 < 700.0**2
    big = np.where(disc[..., None], 1.0, 0.0) * np.ones(4)
    wall, cpu, _ = best(lambda: lightmap.dilate(big, disc, passes=4), repeats=1)
    print(f"dilate 2048x2048x4 disc, 4 passes + nearest: {wall:6.3f} s wall  {cpu:6.3f} s CPU")
    wall, cpu, _ = best(lambda: lightmap.dilate(big, disc, passes=4, rest="zero"), repeats=1)
    print(f"dilate 2048x2048x4 disc, 4 passes, rest zero: {wall:6.3f} s wall  {cpu:6.3f} s CPU")
    wall, cpu, seams = best(lambda: lightmap.seam_pairs(vertex, uv))
    print(f"seam_pairs 20k triangles ({len(seams)} seams): {wall:6.3f} s wall  {cpu:6.3f} s CPU")
    wall, cpu, _ = best(lambda: lightmap.fix_seams(image, seams, covered))
    print(
        f"fix_seams 512x512x6, 10k islands ({len(seams.samples(512)[2])} samples): {wall:6.3f} s wall  {cpu:6.3f} s CPU"
    )
    uv, pos, nrm, vertex = grid(100, "quarters")
    s = texel_samples(uv, pos, nrm, 512)
    covered = s.covered()
    image = lightmap.dilate(
        s.image(np.concatenate([s.positions.mean(axis=0), s.normals.mean(axis=0)], axis=1)), covered
    )
    seams = lightmap.seam_pairs(vertex, uv)
    wall, cpu, _ = best(lambda: lightmap.fix_seams(image, seams, covered))
    print(
        f"fix_seams 512x512x6, 4 islands ({len(seams)} seams, {len(seams.samples(512)[2])} samples): {wall:6.3f} s wall  {cpu:6.3f} s CPU"
    )


if __name__ == "__main__":
    main()
