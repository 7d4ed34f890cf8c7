"""Interreflected transfer in the core: the sphere-with-a-cap closed form, and the pass identities."""

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from prt_addon.core.sh.directions import make_directions
from prt_addon.core.trace import raytrace
from prt_addon.core.transfer import bounce, bounce_hits, quadrature as transfer

pytestmark = pytest.mark.skipif(not raytrace.EMBREE_AVAILABLE, reason="embreex not available")

SQRT_4PI = np.sqrt(4.0 * np.pi)  # L_0 of a uniform radiance 1 (y_0 = 1 / sqrt(4 pi))


def open_sphere(cut_z=0.5, rings=96, segments=192, inward=True):
    """A unit UV sphere whose triangles above z = cut_z are removed, wound so that the geometric
    normal points inward (or outward). Returns (vertices, triangles, opening area fraction)."""
    theta = np.linspace(0.0, np.pi, rings + 1)  # from the north pole
    phi = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    v = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1).reshape(-1, 3)
    i = np.arange(rings)[:, None]
    j = np.arange(segments)[None, :]
    a, b = i * segments + j, i * segments + (j + 1) % segments
    c, d = (i + 1) * segments + (j + 1) % segments, (i + 1) * segments + j
    tris = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    corners = v[tris]
    area_vec = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    area = 0.5 * np.linalg.norm(area_vec, axis=1)
    good = area > 1e-12
    tris, corners, area_vec, area = tris[good], corners[good], area_vec[good], area[good]
    outward = np.einsum("ij,ij->i", area_vec, corners.mean(axis=1)) > 0
    if inward:
        tris[outward] = tris[outward][:, ::-1]
    else:
        tris[~outward] = tris[~outward][:, ::-1]
    keep = corners[:, :, 2].max(axis=1) <= cut_z + 1e-9
    opening = 1.0 - area[keep].sum() / area.sum()
    return v.astype(np.float32), tris[keep].astype(np.int32), float(opening)


def bake_sphere(albedo, bounces, samples=512, order=2, inward=True, kind="FIBONACCI", all_hits=False):
    v, t, f = open_sphere(inward=inward)
    used = np.unique(t)
    # Interior wall points away from the rim and the poles' degenerate fans.
    z = v[used, 2]
    points = used[(z < 0.3) & (z > -0.95)]
    normals = -v.astype(np.float64)  # inward
    dirs = make_directions(kind, samples, 0)
    occ = raytrace.EmbreeOccluder(v, t)
    sink = bounce_hits.HitTransport(
        v, t, t, np.broadcast_to(np.asarray(albedo, float), (len(t), np.size(albedo))), len(dirs.directions)
    )
    comp = transfer.TransferComputation(v, normals, dirs, order, occ, offset=1e-4, hit_sink=sink, threads=2)
    if all_hits:  # the reference: every direction's hits (a bake keeps those of half the set)
        comp.hit_end, comp.hit_weight = comp.n_dirs, 1.0
    direct = comp.run().coeffs
    A = bounce.Transport(comp.hits, len(v), sink.channels)
    bounced = np.zeros((len(v), sink.channels, order * order), np.float32)
    if bounces:
        bounced, _extra = bounce.bounce_passes(direct, A, bounces)
    total = direct[:, None, :] + bounced
    return total[points, :, 0] * SQRT_4PI, f, direct, A, comp


@pytest.mark.parametrize("bounces", [0, 1, 3, 8])
def test_open_sphere_matches_the_closed_form(bounces):
    rho = 0.7
    values, f, *_ = bake_sphere(rho, bounces)
    expected = f * sum((rho * (1.0 - f)) ** k for k in range(bounces + 1))
    # Tolerance: the polygonal sphere (96 x 192) is not quite a sphere, and 512 Fibonacci
    # directions resolve the opening's sharp rim to ~3 % RMS per point (measured 3.0 % direct,
    # 1.2 % at 8 bounces, where the smooth bounced part dominates, gathered over half the
    # directions); the mean over the wall points agreed to 0.02 % at every bounce count.
    assert np.mean(values) == pytest.approx(expected, rel=0.005)
    assert np.sqrt(np.mean((values - expected) ** 2)) < 0.04 * expected


def test_colour_albedo_bounces_per_channel():
    rho = (0.9, 0.5, 0.1)
    values, f, *_ = bake_sphere(rho, 3)
    for c, r in enumerate(rho):
        expected = f * sum((r * (1.0 - f)) ** k for k in range(4))
        assert np.mean(values[:, c]) == pytest.approx(expected, rel=0.005)


def test_each_bounce_adds_less_than_the_one_before():
    rho = 0.8
    _values, f, direct, A, _comp = bake_sphere(rho, 0, samples=256)
    term = direct[:, None, :]
    previous = np.abs(term[:, :, 0]).max()
    for _ in range(4):
        term = A.apply(term)
        now = np.abs(term[:, :, 0]).max()
        assert now <= rho * previous * 1.001
        previous = now


def test_zero_albedo_and_zero_bounces_give_the_direct_bake():
    _values, _f, direct, A, comp = bake_sphere(0.0, 0, samples=128)
    assert not A.apply(direct[:, None, :]).any()
    v, t, _f = open_sphere()
    dirs = make_directions("FIBONACCI", 128, 0)
    plain = transfer.TransferComputation(v, -v.astype(np.float64), dirs, 2, raytrace.EmbreeOccluder(v, t), offset=1e-4)
    assert np.array_equal(plain.run().coeffs, direct)  # recording hits changes nothing
    assert comp.stats.occluded_rays == plain.stats.occluded_rays


@pytest.mark.parametrize("kind", ["FIBONACCI", "STRATIFIED", "UNIFORM"])
def test_bounces_gather_over_half_the_directions_unbiased(kind):
    """Only the first half of the error groups keep their hits (every other Fibonacci direction,
    4 of the 8 groups of i.i.d. directions), weighted N / half: the bounced part's wall mean is
    the one gathered over every direction, to the Monte-Carlo error of the other half."""
    v, t, _f = open_sphere()
    used = np.unique(t)
    z = v[used, 2]
    points = used[(z < 0.3) & (z > -0.95)]
    means = []
    for all_hits in (False, True):
        values, _f, direct, _A, comp = bake_sphere(0.7, 1, kind=kind, all_hits=all_hits)
        means.append(np.mean(values - direct[points, 0] * SQRT_4PI))
        if not all_hits:
            groups = comp.group_bounds.size - 1
            assert comp.hit_end == comp.group_bounds[(groups + 1) // 2] == 256  # 512 directions
    # Measured: 0.02 % (Fibonacci), 0.1 % (stratified), 1.7 % (i.i.d., whose shared 512
    # directions also put the direct part 15 % off the closed form: hence no closed form here).
    assert means[0] == pytest.approx(means[1], rel=0.03 if kind == "UNIFORM" else 0.005)


def test_back_faces_reflect_nothing():
    _values, _f, direct, A, _comp = bake_sphere(0.8, 0, samples=128, inward=False)
    assert A.entries == 0  # every hit is on a back face (the triangles face outward)


def test_hits_do_not_depend_on_threads_or_slices():
    v, t, _f = open_sphere(rings=24, segments=48)
    dirs = make_directions("FIBONACCI", 128, 0)
    results = []
    for threads, chunk in ((1, 1 << 18), (2, 5000)):
        sink = bounce_hits.HitTransport(v, t, t, 0.5, len(dirs.directions))
        comp = transfer.TransferComputation(
            v,
            -v.astype(np.float64),
            dirs,
            3,
            raytrace.EmbreeOccluder(v, t),
            offset=1e-4,
            hit_sink=sink,
            threads=threads,
            chunk_rays=chunk,
        )
        direct = comp.run().coeffs
        results.append(bounce.bounce_passes(direct, bounce.Transport(comp.hits, len(v), 1), 2)[0])
    np.testing.assert_allclose(results[0], results[1], rtol=1e-5, atol=1e-7)


def test_nearest_triangles_and_barycentrics_locate_the_hit():
    v = np.array([[0, 0, 1], [2, 0, 1], [0, 3, 1], [0, 0, 2], [2, 0, 2], [0, 3, 2]], np.float32)
    occ = raytrace.EmbreeOccluder(v, np.array([[3, 4, 5], [0, 1, 2]], np.int32))
    origins = np.array([[0.5, 0.6, 0], [5, 5, 0], [0.2, 0.3, 3]], np.float32)
    dirs = np.array([[0, 0, 1], [0, 0, 1], [0, 0, -1]], np.float32)
    prims = occ.nearest_triangles(origins, dirs)
    assert list(prims) == [1, -1, 0]  # the nearer of two stacked triangles, from either side
    sink = bounce_hits.HitTransport(v, [[3, 4, 5], [0, 1, 2]], [[0, 1, 2]] * 2, 1.0, 1)
    hit = prims >= 0
    ud, wd, det = bounce_hits.hit_barycentrics(sink.corners[prims[hit]], origins[hit], dirs[hit])
    u, w = ud / det, wd / det
    corners = v[[[0, 1, 2], [3, 4, 5]]]
    located = (1 - u)[:, None] * corners[:, 0] + u[:, None] * corners[:, 1] + w[:, None] * corners[:, 2]
    np.testing.assert_allclose(located[:, :2], [[0.5, 0.6], [0.2, 0.3]], atol=1e-6)
    # The triangles' winding normal is +z: the ray going up meets a back face, the one going down a
    # front face (det > 0), whose hit alone the sink keeps.
    assert det[0] < 0 < det[1]
    rows, nodes, weights = sink(np.array([0, 1]), np.array([0, 0]), dirs[hit], np.ones(2), prims[hit], origins[hit])
    assert len(nodes) == 1
    assert rows.expand().tolist() == [1]


@pytest.mark.parametrize(("channels", "x_channels"), [(1, 1), (3, 1), (3, 3)])
def test_transport_apply_equals_the_dense_sum(channels, x_channels, monkeypatch):
    """The sliced-ELLPACK product against np.add.at over the raw entries, for sorted entries
    given as row runs (the bake's case) and for unsorted ones, in grey and in colour."""
    rng = np.random.default_rng(7)
    n_rows, n_nodes, nn = 3000, 500, 9
    rows = np.sort(rng.integers(0, n_rows, 40000)).astype(np.int32)
    nodes = rng.integers(0, n_nodes, rows.size).astype(np.int32)
    weights = rng.random((rows.size, channels), dtype=np.float32)
    x = rng.standard_normal((n_nodes, x_channels, nn)).astype(np.float32)
    expected = np.zeros((n_rows, channels, nn))
    np.add.at(expected, rows, weights[:, :, None].astype(np.float64) * x[nodes].astype(np.float64))
    half = rows.size // 2
    sorted_runs = [
        (bounce_hits.RowRuns(rows[:half]), nodes[:half], weights[:half]),
        (bounce_hits.RowRuns(rows[half:]), nodes[half:], weights[half:]),
    ]
    shuffled = rng.permutation(rows.size)
    unsorted = [(rows[shuffled], nodes[shuffled], weights[shuffled])]
    monkeypatch.setattr(bounce, "SLICES_PER_TASK", 2)  # (6 slices: 3 tasks on the threads)
    for entries in (sorted_runs, unsorted):
        A = bounce.Transport(entries, n_rows, channels)
        assert A.entries == rows.size
        np.testing.assert_allclose(A.apply(x), expected, rtol=1e-4, atol=1e-4)
        with ThreadPoolExecutor(2) as pool:
            assert np.array_equal(A.apply(x, pool), A.apply(x))


def test_hits_before_the_sink_is_set_give_the_same_entries():
    """A LateSink set after the first slices ran (the job starts tracing before the bounce
    system's tables exist) gives the entries of a sink given from the start."""
    v, t, _f = open_sphere(rings=24, segments=48)
    dirs = make_directions("FIBONACCI", 128, 0)
    occ = raytrace.EmbreeOccluder(v, t)
    results = []
    for late in (False, True):
        sink = bounce_hits.HitTransport(v, t, t, 0.5, len(dirs.directions))
        given = bounce_hits.LateSink() if late else sink
        comp = transfer.TransferComputation(
            v, -v.astype(np.float64), dirs, 3, occ, offset=1e-4, hit_sink=given, threads=2, chunk_rays=5000
        )
        if late:
            comp.start()
            early = [e for _a, _b, future in comp._pending for e in future.result()[3]]
            assert early
            assert all(callable(e) for e in early)
            given.set(sink)
        direct = comp.run().coeffs
        A = bounce.Transport(comp.hits, len(v), 1)
        results.append((direct, A.entries, A.apply(direct[:, None, :])))
    assert results[1][1] == results[0][1] > 0
    assert np.array_equal(results[0][0], results[1][0])
    assert np.array_equal(results[0][2], results[1][2])


def test_node_choice_follows_the_barycentric_weights():
    """Hits at one point of a triangle, over a grid of (point, direction) pairs: each corner's
    node is kept with its barycentric weight, and the choices of two points (or two directions)
    are uncorrelated (the hash of the pair)."""
    v = np.array([[0, 0, 1], [1, 0, 1], [0, 1, 1]], np.float32)
    n_rows, n_dirs = 300, 200
    sink = bounce_hits.HitTransport(v, [[0, 1, 2]], [[10, 11, 12]], 1.0, n_dirs, seed=3)
    rows, kdir = np.repeat(np.arange(n_rows), n_dirs), np.tile(np.arange(n_dirs), n_rows)
    m = rows.size
    origins = np.broadcast_to(np.float32([0.2, 0.3, 2.0]), (m, 3))
    dirs = np.broadcast_to(np.float32([0, 0, -1]), (m, 3))
    runs, nodes, weights = sink(rows, kdir, dirs, np.ones(m), np.zeros(m, np.int32), origins)
    assert np.array_equal(runs.expand(), rows)
    assert len(nodes) == m
    np.testing.assert_allclose(weights, 4.0 / n_dirs)
    frequency = np.bincount(nodes - 10, minlength=3) / m
    np.testing.assert_allclose(frequency, [0.5, 0.2, 0.3], atol=0.01)  # (binomial SE < 0.0015)
    first = (nodes == 11).reshape(n_rows, n_dirs).astype(float)
    for a, b in ((first[:-1], first[1:]), (first[:, :-1], first[:, 1:])):  # neighbouring pairs
        assert abs(np.corrcoef(a.ravel(), b.ravel())[0, 1]) < 0.02
