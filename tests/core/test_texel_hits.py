"""Hits on texel-baked meshes as texel nodes: the texel under a hit, the border's borrowed nodes, and the split computation's hits against a point-to-rectangle form factor."""

import math

import numpy as np
import pytest

from prt_addon.core.sh.directions import make_directions
from prt_addon.core.trace import raytrace
from prt_addon.core.transfer import bounce, bounce_hits, split, texel_hits

RES = 8
H = 1.0  # the ceiling's height over the receivers
# A 2 x 2 m ceiling quad at z = H facing down, its UVs (x + 1) / 2, (y + 1) / 2.
CEILING = np.array([(-1, -1, H), (1, -1, H), (1, 1, H), (-1, 1, H)], np.float32)
CEILING_TRIS = np.array([(0, 3, 2), (0, 2, 1)], np.int32)  # (b - a) x (c - a) points down


def _ceiling_uvs():
    return ((CEILING[CEILING_TRIS][..., :2] + 1.0) / 2.0).astype(np.float64)


def _ceiling_sink(rho, n_dirs):
    sink = bounce_hits.HitTransport(CEILING, CEILING_TRIS, np.full((2, 3), -1), rho, n_dirs)
    remap = texel_hits.TexelRemap()
    remap.add(0, 0, texel_hits.TexelNodes(_ceiling_uvs(), np.arange(RES * RES), RES))
    sink.remap = remap
    return sink


def _corner_factor(a, b, h):
    """Form factor from a point to a parallel |a| x |b| rectangle with one corner h above it,
    signed as a times b (so that rectangles add and subtract)."""
    x, y = abs(a) / h, abs(b) / h
    sx, sy = math.sqrt(1 + x * x), math.sqrt(1 + y * y)
    return np.sign(a) * np.sign(b) * (x / sx * math.atan(y / sx) + y / sy * math.atan(x / sy)) / (2 * math.pi)


def _form_factor(x0, y0, half=1.0, h=H):
    """Form factor from an upward point at (x0, y0, 0) to the square [-half, half]^2 at height h:
    the corner rectangles from the point to the square's corners, added and subtracted."""
    f = _corner_factor
    lo, hi = -half, half
    return f(hi - x0, hi - y0, h) - f(lo - x0, hi - y0, h) - f(hi - x0, lo - y0, h) + f(lo - x0, lo - y0, h)


def test_a_vertical_hit_reads_the_texel_above_its_origin():
    rng = np.random.default_rng(1)
    xy = rng.uniform(-0.99, 0.99, (500, 2))
    upper = xy[:, 1] > xy[:, 0]  # triangle 0 is the half above the diagonal y = x
    origins = np.c_[xy, np.zeros(len(xy))].astype(np.float32)
    dirs = np.tile(np.float32([0, 0, 1]), (len(xy), 1))
    sink = _ceiling_sink(1.0, 1)
    rows, nodes, weights = sink(
        np.arange(len(xy)),
        np.zeros(len(xy), np.int64),
        dirs,
        np.ones(len(xy), np.float32),
        (~upper).astype(np.int64),
        origins,
    )
    col = np.floor((xy[:, 0] + 1) / 2 * RES).astype(int)
    row = np.floor((xy[:, 1] + 1) / 2 * RES).astype(int)
    np.testing.assert_array_equal(nodes, row * RES + col)
    np.testing.assert_allclose(weights[:, 0], 4.0)  # albedo 1 times 4 / N, N = 1, cosine 1


def test_border_texels_borrow_the_nearest_covered_node_within_reach():
    res = 8
    lookup = texel_hits.node_lookup(np.array([3 * res + 2]), res, reach=2).reshape(res, res)
    rows, cols = np.mgrid[0:res, 0:res]
    near = np.maximum(abs(rows - 3), abs(cols - 2)) <= 2
    np.testing.assert_array_equal(lookup[near], 0)
    np.testing.assert_array_equal(lookup[~near], -1)
    # Between two covered texels, one an edge neighbour and one a corner neighbour: the edge one.
    two = texel_hits.node_lookup(np.array([0 * res + 1, 1 * res + 2]), res, reach=1).reshape(res, res)
    assert two[0, 2] == 0  # both are edge neighbours: the left one comes first
    assert two[1, 1] == 1  # (1, 2) on its right before (0, 1) above
    assert two[0, 0] == 0
    assert two[0, 3] == 1  # (1, 2) a corner neighbour, the only one near


def test_a_hit_outside_the_uv_square_has_no_node():
    nodes = texel_hits.TexelNodes(np.array([[(0.5, 0.5), (1.5, 0.5), (0.5, 1.5)]]), np.arange(RES * RES), RES)
    got = nodes.nodes([0, 0, 0], [0.0, 0.9, 0.2], [0.0, 0.05, 0.2])
    assert got[0] == (RES // 2) * RES + RES // 2
    assert got[1] == -1  # u = 0.5 + 0.9 = 1.4: off the map
    assert got[2] == int(0.7 * RES) * RES + int(0.7 * RES)


@pytest.mark.skipif(not raytrace.EMBREE_AVAILABLE, reason="embreex not available")
@pytest.mark.parametrize("samples_per_texel", [1, 4])
def test_split_hits_weigh_one_over_s_and_sum_to_the_form_factor(samples_per_texel):
    """Receivers under the ceiling, S samples each: the transport's row sums (t^0 = 1 on every
    ceiling texel) are rho times the point's form factor to the ceiling whatever S, and under the
    centre the hits' mean texel u is 1/2 (symmetry)."""
    rho, n_dirs = 0.6, 16384
    dirs = make_directions("FIBONACCI", n_dirs, 0)
    points = np.array([(0.0, 0.0), (0.5, 0.0), (0.7, -0.6), (1.5, 0.3)])
    s = samples_per_texel
    jitter = np.random.default_rng(2).uniform(-1e-3, 1e-3, (s, len(points), 2))
    positions = np.concatenate([points[None] + jitter, np.zeros((s, len(points), 1))], axis=2)
    normals = np.broadcast_to([0.0, 0.0, 1.0], positions.shape)
    sink = _ceiling_sink(rho, n_dirs)
    comp = split.SplitComputation(
        positions,
        normals,
        dirs,
        2,
        occluder=raytrace.EmbreeOccluder(CEILING, CEILING_TRIS),
        offset=1e-4,
        hit_sink=sink,
        threads=2,
    )
    comp.run()
    transport = bounce.Transport(comp.hits, len(points), sink.channels)
    ones = np.ones((RES * RES, 1, 1), np.float32)
    sums = transport.apply(ones)[:, 0, 0]
    expected = rho * np.array([_form_factor(x, y) for x, y in points])
    np.testing.assert_allclose(
        sums, expected, rtol=0.02
    )  # (quadrature: 1 to 5 % at 1024 to 4096 directions, 0.5 % at 16384)
    u = ((np.arange(RES * RES) % RES + 0.5) / RES).astype(np.float32).reshape(-1, 1, 1)
    mean_u = transport.apply(u)[:, 0, 0] / sums
    assert abs(mean_u[0] - 0.5) < 0.01
    assert mean_u[1] > 0.55  # (a point off centre sees more of the ceiling on its own side)
    comp.hits = []
    assert comp.hits == []
