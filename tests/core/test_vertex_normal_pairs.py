"""mesh_read's vertex-normal pairing (numpy only): it merges only within its tolerance."""

import numpy as np


def test_vertex_normal_pairs_merges_only_within_tolerance():
    """Corner normals of one vertex within NORMAL_TOLERANCE are one pair; farther ones, and the
    same normal at another vertex, stay separate; inverse maps each corner to its pair."""
    from prt_addon.core.transfer import mesh as core_mesh

    tol = core_mesh.NORMAL_TOLERANCE
    up = np.array([0.0, 0.0, 1.0], np.float32)
    tilted = np.array([0.0, 3 * tol, 1.0], np.float32)
    nudged = np.array([0.0, 0.3 * tol, 1.0], np.float32)
    corner_verts = np.array([2, 2, 0, 1, 0, 1], np.int32)
    normals = np.array([up, nudged, up, tilted, up, up])
    vert, pair_normals, inverse = core_mesh.vertex_normal_pairs(corner_verts, normals, 4)
    np.testing.assert_array_equal(vert, [0, 1, 1, 2])  # vertex 3 has no corner
    np.testing.assert_array_equal(vert[inverse], corner_verts)
    np.testing.assert_allclose(pair_normals[inverse], normals, atol=tol)
    assert inverse[3] != inverse[5]  # tilted stays its own pair
    # All corners within tolerance: one pair per vertex that has corners, in vertex order.
    vert, pair_normals, inverse = core_mesh.vertex_normal_pairs(corner_verts[:3], normals[:3], 3)
    np.testing.assert_array_equal(vert, [0, 2])
    np.testing.assert_array_equal(inverse, [1, 1, 0])
