"""Surfaces in contact (a box on the ground, a wall on a floor): no light leaking in at the seam.

A point whose vertex lies in another surface's plane (the bottom row of a box standing on the
ground) used to start its rays in that plane, and the rays going down slipped under the ground:
the bottom row came out twice as bright as Cycles under a uniform white world. The core now also
moves each origin by `offset` into the point's own surface (transfer.inward_tangents), so it lies
on the side of the ground where the box is (docs/bake.md, "Contacts").

This module holds the pure numpy part (the inward tangents and the origins) and the mesh helpers;
the scenes in Blender, against Cycles, are in tests/cycles/test_contact_cycles.py.
"""

import numpy as np
import pytest
from helpers.contact import DIRECTIONS, embree, merged, unit_world_radiance

from prt_addon.core.sh import directions
from prt_addon.core.trace import raytrace
from prt_addon.core.transfer import quadrature as transfer

# --- pure numpy: the inward tangents and the origins ---------------------------------------


def grid_mesh(nx, ny, corner, u, v):
    """A grid of nx x ny quads (two triangles each) spanning corner + [0, 1] u + [0, 1] v."""
    s, t = np.meshgrid(np.linspace(0, 1, nx + 1), np.linspace(0, 1, ny + 1))
    verts = (
        np.asarray(corner, float) + s.reshape(-1, 1) * np.asarray(u, float) + t.reshape(-1, 1) * np.asarray(v, float)
    )
    idx = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    return verts, np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])


def face_normals_of(verts, tris):
    m = np.cross(verts[tris[:, 1]] - verts[tris[:, 0]], verts[tris[:, 2]] - verts[tris[:, 0]])
    return m / np.linalg.norm(m, axis=1, keepdims=True)


def test_inward_tangent_points_into_the_surface_at_a_boundary_and_is_zero_inside():
    # A wall in the plane x = 0 from z = 0 to 1, facing +x.
    verts, tris = grid_mesh(8, 8, (0, -1, 0), (0, 2, 0), (0, 0, 1))
    normals = np.tile([1.0, 0.0, 0.0], (len(verts), 1))
    u = transfer.inward_tangents(verts, normals, verts, tris)
    bottom = np.abs(verts[:, 2]) < 1e-9
    inside = (verts[:, 2] > 0.01) & (verts[:, 2] < 0.99) & (np.abs(verts[:, 1]) < 0.99)
    assert np.allclose(u @ [1.0, 0.0, 0.0], 0.0)  # tangent
    assert np.all(np.linalg.norm(u, axis=1) <= 1.0 + 1e-12)
    # Bottom row (not the two corners): straight up the wall, unit length.
    mid = bottom & (np.abs(verts[:, 1]) < 0.99)
    assert np.allclose(u[mid], [0.0, 0.0, 1.0], atol=1e-6)
    # Corners: into the wall, diagonally.
    corner = bottom & (np.abs(verts[:, 1]) > 0.99)
    assert np.all(u[corner, 2] > 0.5)
    assert np.all(u[corner, 1] * verts[corner, 1] < 0)
    assert np.allclose(u[inside], 0.0, atol=1e-6)  # a symmetric fan


def test_inward_tangent_of_a_flat_box_side_ignores_the_bottom_face():
    # A side face x = 1 (z from 0 to 1) and the bottom face z = 0 of a box, sharing the edge
    # x = 1, z = 0: the side's corner points there (normal +x) point up the side.
    side = grid_mesh(4, 4, (1, 0, 0), (0, 1, 0), (0, 0, 1))
    bottom = grid_mesh(4, 4, (0, 0, 0), (0, 1, 0), (1, 0, 0))  # faces -z
    assert np.allclose(face_normals_of(*side)[:, 0], 1.0)
    assert np.allclose(face_normals_of(*bottom)[:, 2], -1.0)
    verts, tris = merged(side, bottom)
    verts, weld = np.unique(np.round(verts, 9), axis=0, return_inverse=True)  # one mesh
    tris = weld.ravel()[tris]
    edge = np.flatnonzero(
        (np.abs(verts[:, 0] - 1) < 1e-9) & (np.abs(verts[:, 2]) < 1e-9) & (verts[:, 1] > 0.01) & (verts[:, 1] < 0.99)
    )
    # Each edge vertex of a flat-shaded box has two corner normals: two points.
    points = np.concatenate([verts[edge], verts[edge]])
    normals = np.concatenate([np.tile([1.0, 0, 0], (len(edge), 1)), np.tile([0, 0, -1.0], (len(edge), 1))])
    u = transfer.inward_tangents(points, normals, verts, tris, np.concatenate([edge, edge]))
    k = len(edge)
    assert np.allclose(u[:k], [0, 0, 1.0], atol=1e-6)  # side point: up the side
    assert np.allclose(u[k:], [-1.0, 0, 0], atol=1e-6)  # bottom point: into the bottom


def test_inward_tangents_validate_their_input():
    verts, tris = grid_mesh(2, 2, (0, 0, 0), (1, 0, 0), (0, 1, 0))
    normals = np.tile([0, 0, 1.0], (len(verts), 1))
    with pytest.raises(ValueError, match="point_vertex must give one vertex per point"):
        transfer.inward_tangents(verts[:2], normals[:2], verts, tris, [0])
    with pytest.raises(ValueError, match="point_vertex out of range"):
        transfer.inward_tangents(verts[:1], normals[:1], verts, tris, [len(verts)])
    assert np.array_equal(transfer.inward_tangents(verts, normals, verts, tris[:0]), np.zeros((len(verts), 3)))


def wall_on_floor():
    wall = grid_mesh(8, 8, (0, -1, 0), (0, 2, 0), (0, 0, 1))  # x = 0, faces +x
    floor = grid_mesh(16, 16, (-2, -2, 0), (4, 0, 0), (0, 4, 0))
    assert np.allclose(face_normals_of(*wall)[:, 0], 1.0)
    assert np.allclose(face_normals_of(*floor)[:, 2], 1.0)
    return wall, floor


@embree
@pytest.mark.parametrize("contact", [False, True])
def test_wall_on_floor_bottom_row_sees_only_the_upper_half(contact):
    """The wall's foot (normal +x, on the floor) sees the sky above the floor only: E/pi = 1/2
    exactly for an unbounded floor (here 2 to the sides: the same within the quadrature). The
    origins in the floor's plane let the rays going down through: 1.0."""
    (wv, wt), floor = wall_on_floor()
    verts, tris = merged((wv, wt), floor)
    occluder = raytrace.EmbreeOccluder(verts, tris)
    normals = np.tile([1.0, 0.0, 0.0], (len(wv), 1))
    kwargs = {"surface": (wv, wt)} if contact else {}
    result = transfer.TransferComputation(
        wv, normals, directions.make_directions("FIBONACCI", DIRECTIONS, 0), 1, occluder, offset=1e-4 * 2.3, **kwargs
    ).run()
    radiance = unit_world_radiance(result)
    bottom = radiance[np.abs(wv[:, 2]) < 1e-9].mean()
    above = radiance[np.abs(wv[:, 2] - 0.125) < 1e-9].mean()
    print(f"contact={contact}: bottom row {bottom:.4f}, next row {above:.4f}")
    if contact:
        assert abs(bottom - 0.5) < 0.015
        assert bottom < above
    else:  # the old origins: documents the leak this fixes
        assert bottom > 0.9


@embree
def test_origins_move_by_offset_along_the_normal_and_at_most_offset_along_the_surface():
    (wv, wt), _floor = wall_on_floor()
    normals = np.tile([1.0, 0.0, 0.0], (len(wv), 1))
    offset = 1e-3
    comp = transfer.TransferComputation(
        wv, normals, directions.make_directions("FIBONACCI", 16, 0), 1, None, offset=offset, surface=(wv, wt)
    )
    moved = transfer._xyz(comp.origins16).astype(np.float64) - wv
    assert np.allclose(moved[:, 0], offset, rtol=1e-4)
    assert np.all(np.linalg.norm(moved[:, 1:], axis=1) <= offset * (1 + 1e-4))
    assert np.all(moved[np.abs(wv[:, 2]) < 1e-9, 2] > 0.7 * offset)  # the foot: up (corners 45 deg)


@embree
def test_no_contact_results_unchanged_within_noise():
    """A wavy surface under a plane, no contact: the tangential moves of the origins (at most
    `offset`, and ~0 at interior vertices) change the transfer far below its error."""
    n = 40
    x, y = np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n))
    z = 0.3 * np.sin(4 * x) * np.cos(3 * y)
    verts = np.stack([x.ravel(), y.ravel(), z.ravel()], 1)
    idx = np.arange(n * n).reshape(n, n)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    tris = np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])
    m = face_normals_of(verts, tris)
    normals = np.zeros_like(verts)
    for k in range(3):
        np.add.at(normals, tris[:, k], m)
    occluder = raytrace.EmbreeOccluder(verts, tris)
    dirs = directions.make_directions("FIBONACCI", 256, 0)
    old = transfer.TransferComputation(verts, normals, dirs, 3, occluder, offset=2.8e-4).run()
    new = transfer.TransferComputation(verts, normals, dirs, 3, occluder, offset=2.8e-4, surface=(verts, tris)).run()
    diff = np.abs(new.coeffs - old.coeffs).mean()
    print(f"mean |difference| {diff:.2e}, error estimate {old.error_rms():.2e}")
    assert diff < 0.05 * old.error_rms()
