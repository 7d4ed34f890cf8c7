"""Which rays the transfer traces and how: culling, chunks and threads, cancel, memory, occlusion shortcuts.

Pure numpy, no bpy; the analytic occluders come from tests/helpers/occluders.py."""

import tracemalloc

import numpy as np
import pytest
from helpers.occluders import CupOccluder, PlaneOccluder

from prt_addon.core.sh.directions import make_directions
from prt_addon.core.trace import raytrace
from prt_addon.core.transfer import quadrature as transfer


def test_horizon_culling_and_counts():
    rng = np.random.default_rng(0)
    n = rng.normal(size=(300, 3))
    dirs = make_directions("STRATIFIED", 200, 5)
    res = transfer.compute_transfer(np.zeros((300, 3)), n, dirs, 3, PlaneOccluder((0, 0, -5), (0, 0, 1)), offset=1e-3)
    above = (n / np.linalg.norm(n, axis=1, keepdims=True)) @ dirs.directions.T > 0
    s = res.stats
    assert s.rays_traced == above.sum()
    assert s.skipped_below_horizon == above.size - above.sum()
    assert s.rays_traced + s.rays_skipped == s.candidate_rays


def test_unoccludable_points_trace_nothing():
    n = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    p = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    dirs = make_directions("FIBONACCI", 256, 0)
    box_below = np.array([[[-1, -1, -1], [1, 1, 0.5]]], dtype=float)
    res = transfer.compute_transfer(
        p, n, dirs, 3, PlaneOccluder((0, 0, 0), (0, 0, 1)), offset=1e-4, self_occludes=False, other_boxes=box_below
    )
    # The point facing up sees nothing above its tangent plane; the one facing down is traced.
    up = int(np.count_nonzero(dirs.directions[:, 2] > 0))
    down = int(np.count_nonzero(dirs.directions[:, 2] < 0))
    assert res.stats.rays_traced == down
    assert res.stats.skipped_unoccludable == up
    free = transfer.compute_transfer(p, n, dirs, 3, None)
    np.testing.assert_array_equal(res.coeffs[0], free.coeffs[0])


def test_chunks_threads_and_direction_blocks_give_identical_results():
    rng = np.random.default_rng(1)
    p = rng.normal(size=(257, 3))
    n = rng.normal(size=(257, 3))
    dirs = make_directions("FIBONACCI", 300, 6)
    occ = CupOccluder()
    ref = transfer.compute_transfer(p, n, dirs, 4, occ, offset=1e-4, threads=1)
    for chunk, threads in [(1000, 2), (64, 2), (7, 1), (1 << 22, 2)]:
        res = transfer.compute_transfer(p, n, dirs, 4, occ, offset=1e-4, chunk_rays=chunk, threads=threads)
        np.testing.assert_allclose(res.coeffs, ref.coeffs, rtol=0, atol=2e-7)
        np.testing.assert_allclose(res.error, ref.error, rtol=1e-5, atol=1e-7)
        assert res.stats.rays_traced == ref.stats.rays_traced


def test_cancel():
    dirs = make_directions("FIBONACCI", 64, 0)
    comp = transfer.TransferComputation(np.zeros((100, 3)), np.ones((100, 3)), dirs, 3, chunk_rays=64 * 10, threads=1)
    assert comp.step()
    comp.cancel()
    with pytest.raises(transfer.Cancelled):
        comp.step()


def _peak_bytes(samples, chunk_rays, kind="FIBONACCI", order=4):
    rng = np.random.default_rng(2)
    p = rng.normal(size=(20000, 3))
    dirs = make_directions(kind, samples, 0)
    dirs.basis(order)
    tracemalloc.start()
    comp = transfer.TransferComputation(
        p, p, dirs, order, PlaneOccluder((0, 0, -50), (0, 0, 1)), offset=1e-3, chunk_rays=chunk_rays, threads=2
    )
    base = tracemalloc.get_traced_memory()[0]
    tracemalloc.reset_peak()
    comp.run()
    peak = tracemalloc.get_traced_memory()[1] - base
    tracemalloc.stop()
    return peak


def test_peak_memory_is_bounded_by_the_chunk_size():
    chunk = 1 << 16
    small = _peak_bytes(256, chunk)
    large = _peak_bytes(2048, chunk)
    # The analytic occluder itself uses ~100 bytes per ray of float64 temporaries (rays are
    # about half the candidates); the outputs (20000 x 16 float32 + errors) come on top.
    bound = chunk * (transfer.RAY_BYTES + 50) + 20000 * 68
    assert small < bound and large < bound, (small, large, bound)
    assert large < 1.3 * small  # 8 times the samples, about the same memory


def test_peak_memory_bound_holds_at_high_order_few_samples_and_eight_groups():
    """Order 16 (256 coefficients) with 16 uniform directions (8 error groups): the per-point
    accumulators, (8 + 3) * 256 float64 = 22 kB per point, count in the slice budget, so the
    working set stays within the same bound (before, a slice of 16384 points took ~0.4 GB)."""
    chunk = 1 << 16
    peak = _peak_bytes(16, chunk, kind="UNIFORM", order=16)
    outputs = 20000 * (256 * 4 + 4)  # coefficients float32 + errors
    bound = chunk * (transfer.RAY_BYTES + 50) + outputs
    assert peak < bound, (peak, bound)


def _box(lo=(-1, -1, -1), hi=(1, 1, 1)):
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    v = np.array(
        [
            [x0, y0, z0],
            [x1, y0, z0],
            [x1, y1, z0],
            [x0, y1, z0],
            [x0, y0, z1],
            [x1, y0, z1],
            [x1, y1, z1],
            [x0, y1, z1],
        ],
        float,
    )
    quads = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    t = [(a, b, c) for a, b, c, d in quads] + [(a, c, d) for a, b, c, d in quads]
    return v, np.array(t)


def test_convexity_and_planarity_tests():
    v, t = _box()
    assert raytrace.is_closed_convex(v, t)
    assert raytrace.cannot_self_occlude(v, t)
    dented = v.copy()
    dented[6] = [0.2, 0.2, 0.2]  # pull one corner inside
    assert not raytrace.is_closed_convex(dented, t)
    assert not raytrace.is_closed_convex(v, t[:-1])  # open
    assert not raytrace.is_closed_convex(v, t[:, ::-1])  # inside out
    v2, t2 = _box((3, 3, 3), (4, 4, 4))
    both_v = np.vstack([v, v2])
    both_t = np.vstack([t, t2 + 8])
    assert not raytrace.cannot_self_occlude(both_v, both_t)  # two bodies shadow each other
    grid = np.array([[x, y, 0.0] for y in range(3) for x in range(3)])
    gt = np.array([(0, 1, 4), (0, 4, 3), (1, 2, 5), (1, 5, 4), (3, 4, 7), (3, 7, 6), (4, 5, 8), (4, 8, 7)])
    assert raytrace.is_planar(grid, gt)
    assert raytrace.cannot_self_occlude(grid, gt)
    bent = grid.copy()
    bent[8, 2] = 0.5
    assert not raytrace.cannot_self_occlude(bent, gt)
    # A plane in any orientation and position is planar up to rel_tol of its size, not beyond.
    rng = np.random.default_rng(5)
    rotation = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    tilted = (1e3 * grid) @ rotation.T + [5e3, -2e3, 7e3]
    size = np.linalg.norm(tilted.max(axis=0) - tilted.min(axis=0))
    for noise, planar in ((1e-8, True), (1e-4, False)):
        shaken = tilted + noise * size * rotation[:, 2] * rng.choice([-1.0, 1.0], size=(9, 1))
        assert raytrace.is_planar(shaken, gt) == planar
    assert not raytrace.is_planar(np.zeros((9, 3)), gt)  # all at one point: no plane


def test_box_can_occlude():
    boxes = np.array([[[-1, -1, 0], [1, 1, 1]]], float)
    p = np.array([[0, 0, 2], [0, 0, 2], [3, 0, 0.5]], float)
    n = np.array([[0, 0, 1], [0, 0, -1], [1, 0, 0]], float)
    assert raytrace.box_can_occlude(p, n, boxes).tolist() == [False, True, False]
