"""The contact fix in Blender scenes without Cycles: the BVH tree backend gets the same fix as Embree."""

import numpy as np
from helpers.contact import _add, _grid, _prt, _wall, embree


@embree
def test_bvhtree_backend_gets_the_same_contact_fix(empty_scene, bpy_module):
    """The BVHTree fallback traces the same origins: same result as Embree at the seam."""
    bpy, scene = bpy_module, empty_scene
    floor = _add(bpy, scene, "floor", _grid(4.0, 8))
    wall = _add(bpy, scene, "wall", _wall(2.0, 1.0, 4))
    new_e, old_e, pos, _n = _prt([wall, floor], 0, "EMBREE")
    new_b, old_b, _p, _n = _prt([wall, floor], 0, "BVHTREE")
    bottom = np.abs(pos[:, 2]) < 1e-9
    print(
        "bottom row: embree",
        new_e[bottom].mean(),
        "bvhtree",
        new_b[bottom].mean(),
        "before",
        old_e[bottom].mean(),
        old_b[bottom].mean(),
    )
    assert abs(new_b[bottom].mean() - 0.5) < 0.015
    assert np.abs(new_b - new_e).max() < 0.01
