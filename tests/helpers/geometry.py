"""Random rays and a wavy grid for the ray tracers (pure numpy; also imported by subprocesses)."""

import numpy as np


def wavy_grid(n=120):
    x, y = np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n))
    vertices = np.stack([x.ravel(), y.ravel(), 0.3 * np.sin(5 * x.ravel()) * np.cos(3 * y.ravel())], 1)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    return vertices, np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])


def random_rays(count, seed):
    rng = np.random.default_rng(seed)
    origins = rng.uniform(-1.2, 1.2, (count, 3)).astype(np.float32)
    origins[:, 2] = rng.uniform(-0.5, 0.5, count)
    return origins, rng.normal(size=(count, 3)).astype(np.float32)
