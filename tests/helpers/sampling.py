"""Random inputs shared by the core tests (pure numpy)."""

import numpy as np


def random_directions(count, seed):
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(count, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)
