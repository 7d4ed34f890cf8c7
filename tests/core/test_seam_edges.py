"""UV seams are made to agree only across smooth edges: across a hard edge the light is not continuous."""

import numpy as np

from prt_addon.core.transfer import lightmap


def _two_triangles(fold_normal):
    """Two triangles sharing the edge (1, 2), cut in UV; the second's corner normals are `fold_normal`."""
    corner_vertices = np.array([[0, 1, 2], [2, 1, 3]])
    uvs = np.array([[[0.0, 0.0], [0.4, 0.0], [0.0, 0.4]], [[0.6, 1.0], [1.0, 0.6], [1.0, 1.0]]])
    up = np.array([0.0, 0.0, 1.0])
    normals = np.array([[up, up, up], [fold_normal] * 3])
    return corner_vertices, uvs, normals


def test_a_smooth_cut_edge_is_a_seam_and_a_hard_one_is_not():
    cv, uvs, smooth = _two_triangles([0.0, 0.0, 1.0])
    assert len(lightmap.seam_pairs(cv, uvs, normals=smooth)) == 1
    cv, uvs, hard = _two_triangles([1.0, 0.0, 0.0])
    assert len(lightmap.seam_pairs(cv, uvs, normals=hard)) == 0
    assert len(lightmap.seam_pairs(cv, uvs)) == 1  # without normals every cut edge is a seam
