"""The back side of open surfaces: boundary edges, the turned-over points and faces, and the back transfer's closed forms."""

import math

import numpy as np
from helpers.occluders import PlaneOccluder

from prt_addon.core.sh.directions import make_directions
from prt_addon.core.transfer import back, quadrature as transfer
from prt_addon.core.transfer.contact import inward_tangents
from prt_addon.core.transfer.mesh import BakePoints

QUAD = np.array([[-1.0, -1.0, 1.0], [1.0, -1.0, 1.0], [1.0, 1.0, 1.0], [-1.0, 1.0, 1.0]])
QUAD_TRIANGLES = np.array([[0, 1, 2], [0, 2, 3]])  # counter-clockwise seen from +z: normal +z
UP = np.tile([0.0, 0.0, 1.0], (4, 1))


def _tetrahedron():
    v = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    return v, np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def test_boundary_edges_tell_open_meshes_from_closed_ones():
    assert back.boundary_edges(QUAD_TRIANGLES) == 4  # the diagonal is shared
    assert back.is_open(QUAD_TRIANGLES)
    _v, closed = _tetrahedron()
    assert back.boundary_edges(closed) == 0 and not back.is_open(closed)
    assert back.boundary_edges(closed[:-1]) == 3  # one face removed: its three edges
    assert back.boundary_edges(closed[:, ::-1]) == 0  # winding does not matter
    assert not back.is_open(np.zeros((0, 3), int))


def test_turned_over_points_and_faces():
    points = BakePoints("POINT", QUAD.copy(), UP.copy(), None)
    turned = back.turned_over(points)
    assert np.array_equal(turned.normals, -UP) and np.array_equal(turned.positions, QUAD)
    assert np.array_equal(points.normals, UP)  # the front's points are left as they were
    flipped = back.turned_over_triangles(QUAD_TRIANGLES)
    assert flipped.dtype == np.int32
    e1, e2 = QUAD[flipped[:, 1]] - QUAD[flipped[:, 0]], QUAD[flipped[:, 2]] - QUAD[flipped[:, 0]]
    assert np.all(np.cross(e1, e2)[:, 2] < 0)  # its face normals point down


def test_contact_tangents_of_the_back_need_the_faces_turned_over():
    """The back's boundary points move into the quad as the front's do; with the front's faces
    (their normals opposite to the point's) every corner's weight is 0 and the tangent vanishes."""
    front = inward_tangents(QUAD, UP, QUAD, QUAD_TRIANGLES)
    behind = inward_tangents(QUAD, -UP, QUAD, back.turned_over_triangles(QUAD_TRIANGLES))
    assert np.all(np.linalg.norm(front, axis=1) > 0.5)
    np.testing.assert_allclose(behind, front, atol=1e-6)
    assert np.abs(inward_tangents(QUAD, -UP, QUAD, QUAD_TRIANGLES)).max() < 1e-6


def test_unoccluded_back_transfer_is_the_front_mirrored():
    """A plane alone: t_back(w) = t_front(-w), i.e. band l times (-1)^l, and E/pi = sqrt(4 pi) t_0 = 1
    on each side under a uniform sky of radiance 1 (to the direction set's quadrature error)."""
    order = 4
    dirs = make_directions("FIBONACCI", 4096, 0)
    front = transfer.compute_transfer(QUAD, UP, dirs, order).coeffs.astype(np.float64)
    behind = transfer.compute_transfer(QUAD, -UP, dirs, order).coeffs.astype(np.float64)
    sign = np.array([(-1.0) ** l for l in range(order) for _m in range(2 * l + 1)])
    np.testing.assert_allclose(math.sqrt(4 * math.pi) * front[:, 0], 1.0, atol=2e-3)
    np.testing.assert_allclose(math.sqrt(4 * math.pi) * behind[:, 0], 1.0, atol=2e-3)
    np.testing.assert_allclose(behind, front * sign, atol=2e-3)


def test_back_of_a_roof_sees_the_floor():
    """A roof at z = 1 over an infinite floor at z = 0: lit from above, nothing reaches its back."""
    dirs = make_directions("FIBONACCI", 1024, 0)
    floor = PlaneOccluder((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    front = transfer.compute_transfer(QUAD, UP, dirs, 3, floor, offset=1e-4).coeffs
    behind = transfer.compute_transfer(QUAD, -UP, dirs, 3, floor, offset=1e-4).coeffs
    np.testing.assert_allclose(math.sqrt(4 * math.pi) * front[:, 0], 1.0, atol=5e-3)
    assert np.abs(behind).max() == 0.0
