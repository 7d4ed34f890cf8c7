"""Rays as 16-byte rows: origins and directions packed as (x, y, z, 0) float32 in one item.

numpy's take() and repeat() copy 16-byte items in a fast path but 12-byte rows element by element
(measured 3 to 5 times slower, docs/bake.md); xyz() gives the (n, 3) float32 view Embree reads.
"""

import numpy as np

RAY16 = np.complex128


def rays16(xyz_rows):
    """(n,) 16-byte items of the (n, 3) points or directions."""
    rows = np.zeros((len(xyz_rows), 4), dtype=np.float32)
    rows[:, :3] = xyz_rows
    return rows.view(RAY16).reshape(-1)


def xyz(items):
    """The (n, 3) float32 view of (n,) 16-byte items."""
    return items.view(np.float32).reshape(-1, 4)[:, :3]
