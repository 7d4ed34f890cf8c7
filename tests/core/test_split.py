"""Transfer over several sample positions per element with the direction set split between them (core.transfer.split)."""

import numpy as np
import pytest
from helpers.occluders import WallOccluder

from prt_addon.core.sh import analytic
from prt_addon.core.sh.directions import make_directions
from prt_addon.core.trace.raytrace import EMBREE_AVAILABLE, EmbreeOccluder
from prt_addon.core.transfer import contact, quadrature as transfer, split


def _points(count, seed=0):
    rng = np.random.default_rng(seed)
    positions = np.c_[rng.uniform(-1, 0, count), rng.uniform(-1, 1, count), np.full(count, 0.01)]
    normals = rng.normal(size=(count, 3)) * 0.3 + [0.0, 0.0, 1.0]
    return positions, normals / np.linalg.norm(normals, axis=1, keepdims=True)


def test_the_subsets_partition_the_direction_set():
    dirs = make_directions("FIBONACCI", 250, seed=3)
    subsets = split.direction_subsets(dirs, 4)
    merged = np.concatenate([s.directions for s in subsets])
    assert sum(s.count for s in subsets) == 250
    assert np.array_equal(np.sort(merged.view("f8,f8,f8"), axis=0), np.sort(dirs.directions.view("f8,f8,f8"), axis=0))


@pytest.mark.parametrize("occluded", [False, True])
def test_one_position_repeated_is_the_full_sets_quadrature(occluded):
    """S copies of one point: the mean of the subsets' quadratures is the full set's, term by term."""
    positions, normals = _points(40)
    dirs = make_directions("FIBONACCI", 256, seed=1)
    occluder = WallOccluder(0.2, 0.5) if occluded else None
    full = transfer.compute_transfer(positions, normals, dirs, 4, occluder=occluder, offset=1e-4, threads=1)
    stacked = np.broadcast_to(positions, (4, *positions.shape))
    stacked_n = np.broadcast_to(normals, (4, *normals.shape))
    comp = split.SplitComputation(stacked, stacked_n, dirs, 4, occluder=occluder, offset=1e-4, threads=1)
    result = comp.run()
    np.testing.assert_allclose(result.coeffs, full.coeffs, rtol=0, atol=2e-6)
    assert comp.done == comp.total == 40
    assert result.stats.rays_traced == full.stats.rays_traced


def test_distinct_positions_average_their_own_quadratures():
    """Each part is the quadrature of its own positions over its own subset: t = mean over s."""
    dirs = make_directions("FIBONACCI", 129, seed=2)  # (3 subsets of 43: the mean of theirs is the sum)
    subsets = split.direction_subsets(dirs, 3)
    wall = WallOccluder(0.2, 0.5)
    parts = [_points(30, seed=s) for s in range(3)]
    comp = split.SplitComputation(
        np.stack([p for p, _ in parts]), np.stack([n for _, n in parts]), dirs, 3, occluder=wall, offset=1e-4, threads=2
    )
    got = comp.run().coeffs
    want = np.mean(
        [
            transfer.compute_transfer(p, n, sub, 3, occluder=wall, offset=1e-4, threads=1).coeffs
            for (p, n), sub in zip(parts, subsets)
        ],
        axis=0,
    )
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-6)


def test_open_points_converge_to_the_clamped_cosine():
    positions, normals = _points(20)
    dirs = make_directions("FIBONACCI", 1024, seed=0)
    stacked = np.stack([positions + [0.01 * s, 0.0, 0.0] for s in range(4)])
    result = split.SplitComputation(stacked, np.broadcast_to(normals, stacked.shape), dirs, 3, threads=1).run()
    closed = np.stack([analytic.clamped_cosine_coeffs(3, n) for n in normals])  # (of max(0, n.w) / pi)
    np.testing.assert_allclose(result.coeffs, closed, atol=4e-3)


def test_cancel_stops_a_split_computation():
    positions, normals = _points(500)
    dirs = make_directions("FIBONACCI", 64)
    comp = split.SplitComputation(
        np.stack([positions] * 2),
        np.stack([normals] * 2),
        dirs,
        2,
        occluder=WallOccluder(0.2, 0.5),
        chunk_rays=256,
        threads=1,
    )
    assert comp.step()
    comp.cancel()
    with pytest.raises(transfer.Cancelled):
        comp.step()
    comp.close()


@pytest.mark.skipif(not EMBREE_AVAILABLE, reason="embreex is not installed")
def test_a_face_lying_on_another_is_under_it_and_one_above_is_not():
    """A box's bottom face on the floor (normal -z at z = 0, the floor's plane): under the floor.
    Lifted by 3 offsets, or facing up on it, it is not."""
    floor = np.array([[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]], np.float32)
    tris = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    occluder = EmbreeOccluder(floor, tris)
    offset = 1e-3
    points = np.array([[0.1, 0.2, 0.0], [0.3, -0.4, 3 * offset], [0.5, 0.5, 0.0], [5.0, 5.0, 0.0]])
    normals = np.array([[0, 0, -1], [0, 0, -1], [0, 0, 1], [0, 0, -1]], float)
    under = contact.under_other_surfaces(points, normals, offset, occluder, floor, tris)
    assert under.tolist() == [True, False, False, False]


def test_computations_accumulating_into_one_array_give_the_mean_of_their_results():
    """accumulate=: two computations adding t / 2 into one float32 array give the mean of their
    own coefficients, and a wrongly shaped array is refused."""
    (p0, n0), (p1, n1) = _points(50, seed=4), _points(50, seed=5)
    dirs = make_directions("FIBONACCI", 128, seed=3)
    wall = WallOccluder(0.2, 0.5)
    own = [transfer.compute_transfer(p, n, dirs, 3, occluder=wall, threads=1).coeffs for p, n in ((p0, n0), (p1, n1))]
    total = np.zeros((50, 9), np.float32)
    for p, n in ((p0, n0), (p1, n1)):
        comp = transfer.TransferComputation(
            p, n, dirs, 3, occluder=wall, threads=1, accumulate=total, accumulate_weight=0.5
        )
        assert comp.run().coeffs is total
    np.testing.assert_allclose(total, 0.5 * (own[0] + own[1]), rtol=0, atol=1e-6)
    with pytest.raises(ValueError, match="accumulate"):
        transfer.TransferComputation(p0, n0, dirs, 3, accumulate=np.zeros((50, 16), np.float32))
