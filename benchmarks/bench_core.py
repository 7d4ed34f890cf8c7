"""Core benchmark: projection of a 1024x512 HDRI and SH rotation, per order.

Run: .venv/bin/python benchmarks/bench_core.py   (after `bash scripts/test.sh` made the venv)
Prints medians of repeated runs; the separable projection is compared side by side, in the same
run, with evaluating the basis at every pixel (the naive method), as a ratio.
"""

import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from prt_addon.core.sh import basis as sh, directions, projection, rotation


def median_seconds(fn, repeats):
    fn()  # warm caches (rotation plans, allocator)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def naive_projection(pixels, order):
    height, width = pixels.shape[:2]
    dirs = projection.pixel_directions(height, width).reshape(-1, 3)
    weights = np.repeat(projection.pixel_solid_angles(height, width), width)
    rgb = pixels[:, :, :3].reshape(-1, 3).astype(np.float64) * weights[:, None]
    out = np.zeros((order * order, 3))
    for start in range(0, len(dirs), 32768):
        out += sh.sh_basis(dirs[start : start + 32768], order).T @ rgb[start : start + 32768]
    return out


def main():
    rng = np.random.default_rng(0)
    pixels = (rng.random((512, 1024, 4)) * 10).astype(np.float32)
    print("Projection of a 1024x512 RGBA float32 image (median seconds)")
    print(f"{'order':>5} {'separable':>10} {'per-pixel basis':>16} {'speed-up':>9}")
    for order in (3, 8, 16):
        fast = median_seconds(lambda: projection.project_equirect(pixels, order), 7)
        naive = median_seconds(lambda: naive_projection(pixels, order), 2)
        print(f"{order:>5} {fast * 1e3:>8.1f}ms {naive * 1e3:>14.1f}ms {naive / fast:>8.1f}x")

    print("\nRotation of an RGB coefficient vector by a general 3x3 rotation (median)")
    print(f"{'order':>5} {'rotate()':>10} {'matrix':>10} {'rotate_z()':>10}")
    r = directions.random_rotation(rng)
    for order in range(1, 17):
        coeffs = rng.normal(size=(order * order, 3))
        apply_time = median_seconds(lambda: rotation.rotate(coeffs, r), 50)
        matrix_time = median_seconds(lambda: rotation.rotation_matrix(r, order), 50)
        z_time = median_seconds(lambda: rotation.rotate_z(coeffs, 0.3), 50)
        print(f"{order:>5} {apply_time * 1e3:>8.3f}ms {matrix_time * 1e3:>8.3f}ms {z_time * 1e3:>8.3f}ms")


if __name__ == "__main__":
    main()
