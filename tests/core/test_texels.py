"""Texel samples of a UV layout: coverage, sample placement, snapping, inset, overlaps (pure numpy)."""

import numpy as np
import pytest

from prt_addon.core.transfer.texels import SAMPLE_OFFSETS, texel_samples

QUAD = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], float)


def affine_quad(uv_box=(0.0, 0.0, 1.0, 1.0)):
    """Two triangles over the UV box, positions the affine map O + u A + v B, corner normals the
    affine field (u - 0.5, v - 0.5, 1): both are reproduced exactly by interpolation."""
    u0, v0, u1, v1 = uv_box
    uv = np.stack([u0 + QUAD[..., 0] * (u1 - u0), v0 + QUAD[..., 1] * (v1 - v0)], axis=-1)
    o, a, b = np.array([1.0, -2.0, 0.5]), np.array([2.0, 0.5, 0.0]), np.array([-0.3, 1.5, 0.7])
    pos = o + uv[..., :1] * a + uv[..., 1:] * b
    nrm = np.concatenate([uv - 0.5, np.ones(uv.shape[:-1] + (1,))], axis=-1)
    return uv, pos, nrm, (o, a, b)


def sample_uvs(s, offsets=SAMPLE_OFFSETS):
    row, col = np.divmod(s.texels, s.resolution)
    return np.stack([(col[None] + offsets[:, :1]) / s.resolution, (row[None] + offsets[:, 1:]) / s.resolution], -1)


def clip_area(poly, x0, y0, x1, y1):
    """Area of a convex polygon clipped to a box (Sutherland-Hodgman), for brute-force coverage."""
    for axis, bound, keep_above in ((0, x0, True), (0, x1, False), (1, y0, True), (1, y1, False)):
        out = []
        for i in range(len(poly)):
            p, q = poly[i], poly[(i + 1) % len(poly)]
            pin = p[axis] >= bound if keep_above else p[axis] <= bound
            qin = q[axis] >= bound if keep_above else q[axis] <= bound
            if pin:
                out.append(p)
            if pin != qin:
                t = (bound - p[axis]) / (q[axis] - p[axis])
                out.append(p + t * (q - p))
        poly = out
        if not poly:
            return 0.0
    p = np.array(poly)
    return 0.5 * abs(np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]))


def point_triangle(p, tri):
    """(distance, closest point, barycentrics) of a 2D point to a triangle, by brute force."""
    m = np.array([tri[1] - tri[0], tri[2] - tri[0]]).T
    b12 = np.linalg.solve(m, p - tri[0])
    bary = np.array([1 - b12.sum(), *b12])
    if bary.min() >= 0:
        return 0.0, p, bary
    best = (np.inf, None, None)
    for j in range(3):
        a, b = tri[j], tri[(j + 1) % 3]
        t = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0, 1)
        q = a + t * (b - a)
        if np.linalg.norm(p - q) < best[0]:
            w = np.zeros(3)
            w[j], w[(j + 1) % 3] = 1 - t, t
            best = (np.linalg.norm(p - q), q, w)
    return best


@pytest.mark.parametrize("res", [1, 8, 37, 64])
def test_full_quad_covers_every_texel_and_samples_follow_the_affine_map(res):
    uv, pos, nrm, (o, a, b) = affine_quad()
    s = texel_samples(uv, pos, nrm, res)
    assert s.count == res * res and np.array_equal(s.texels, np.arange(res * res))
    suv = sample_uvs(s)
    np.testing.assert_allclose(s.positions, o + suv[..., :1] * a + suv[..., 1:] * b, atol=1e-12)
    field = np.concatenate([suv - 0.5, np.ones(suv.shape[:-1] + (1,))], -1)
    np.testing.assert_allclose(s.normals, field / np.linalg.norm(field, axis=-1, keepdims=True), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(s.normals, axis=-1), 1.0, atol=1e-12)
    assert (s.overlapping, s.outside, s.degenerate) == (0, 0, 0)
    assert s.covered().all()


@pytest.mark.parametrize("res", [7, 8, 10, 33])
@pytest.mark.parametrize("box", [(0.25, 0.25, 0.75, 0.75), (0.13, 0.27, 0.61, 0.9)])
def test_inner_rectangle_covers_exactly_the_texels_it_overlaps(res, box):
    uv, pos, nrm, _ = affine_quad(box)
    s = texel_samples(uv, pos, nrm, res)
    u0, v0, u1, v1 = box
    cols = np.arange(int(np.floor(u0 * res)), int(np.ceil(u1 * res)))
    rows = np.arange(int(np.floor(v0 * res)), int(np.ceil(v1 * res)))
    assert s.count == len(cols) * len(rows)
    assert np.array_equal(s.texels, (rows[:, None] * res + cols[None, :]).ravel())


def test_row_zero_is_the_bottom_of_the_map():
    uv, pos, nrm, _ = affine_quad((0.5, 0.0, 1.0, 0.25))
    s = texel_samples(uv, pos, nrm, 8)
    expected = np.zeros((8, 8), bool)
    expected[0:2, 4:8] = True  # rows are v, columns u
    assert np.array_equal(s.covered(), expected)


def random_layout(count, seed, res, thin=False):
    rng = np.random.default_rng(seed)
    centre = rng.uniform(0.1, 0.9, (count, 1, 2))
    uv = centre + rng.normal(0, 0.08, (count, 3, 2))
    if thin:  # narrower than a texel: squash the triangles towards a line
        uv[:, 2] = uv[:, 0] + 0.5 * (uv[:, 1] - uv[:, 0]) + rng.uniform(0.05, 0.4, (count, 2)) / res
    pos = np.concatenate([uv * 3.0, rng.uniform(-0.5, 0.5, (count, 3, 1))], -1)
    nrm = rng.normal(0, 0.2, (count, 3, 3)) + [0, 0, 1]
    return uv, pos, nrm


@pytest.mark.parametrize(("seed", "thin"), [(0, False), (1, True), (2, False)])
def test_samples_follow_the_rules_against_brute_force(seed, thin):
    res = 16
    uv, pos, nrm = random_layout(12, seed, res, thin)
    s = texel_samples(uv, pos, nrm, res)
    x = uv * res
    overlap = np.array(
        [
            [clip_area(list(x[t]), c, r, c + 1, r + 1) > 1e-12 for t in range(len(x))]
            for r in range(res)
            for c in range(res)
        ]
    )
    assert np.array_equal(s.texels, np.flatnonzero(overlap.any(axis=1)))
    if thin:
        assert s.count >= len(uv)  # every thin triangle got texels
    suv = sample_uvs(s)
    for k, texel in enumerate(s.texels):
        candidates = np.flatnonzero(overlap[texel])
        for si in range(len(SAMPLE_OFFSETS)):
            p = suv[si, k] * res
            found = [(point_triangle(p, x[t]), t) for t in candidates]
            inside = [t for (d, _q, _b), t in found if d == 0.0]
            want = min(inside) if inside else min(found, key=lambda f: f[0][0])[1]
            assert s.triangles[si, k] == want
            (_d, q, bary) = point_triangle(p, x[want])
            np.testing.assert_allclose(s.barycentrics[si, k], bary, atol=1e-9)
            np.testing.assert_allclose(s.barycentrics[si, k] @ x[want], q, atol=1e-9)
    assert (s.barycentrics >= 0).all()
    np.testing.assert_allclose(s.barycentrics.sum(-1), 1.0, atol=1e-12)
    corners = pos[s.triangles]
    np.testing.assert_allclose(s.positions, np.einsum("spj,spjk->spk", s.barycentrics, corners), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(s.normals, axis=-1), 1.0, atol=1e-12)


def edge_distances(points, tri):
    """(..., 3) distances in 3D of points in a triangle's plane from its three edge lines."""
    out = []
    for j in range(3):
        a, b = tri[..., (j + 1) % 3, :], tri[..., (j + 2) % 3, :]
        e = (b - a) / np.linalg.norm(b - a, axis=-1, keepdims=True)
        w = points - a
        out.append(np.linalg.norm(w - np.sum(w * e, -1, keepdims=True) * e, axis=-1))
    return np.stack(out, -1)


@pytest.mark.parametrize("inset", [0.002, 0.02, 1.0])
def test_inset_keeps_samples_away_from_the_edges(inset):
    res = 32
    uv, pos, nrm = random_layout(20, 3, res, thin=False)
    plain = texel_samples(uv, pos, nrm, res)
    s = texel_samples(uv, pos, nrm, res, inset=inset)
    assert np.array_equal(s.texels, plain.texels) and np.array_equal(s.triangles, plain.triangles)
    tri = pos[s.triangles]
    a, b, c = tri[..., 0, :], tri[..., 1, :], tri[..., 2, :]
    twice_area = np.linalg.norm(np.cross(b - a, c - a), axis=-1)
    inradius = twice_area / (
        np.linalg.norm(b - a, axis=-1) + np.linalg.norm(c - b, axis=-1) + np.linalg.norm(a - c, axis=-1)
    )
    target = np.minimum(inset, inradius / 3)
    assert (edge_distances(s.positions, tri).min(-1) >= target * (1 - 1e-9)).all()
    # Samples already that far inside stay where they were.
    far = edge_distances(plain.positions, tri).min(-1) >= target
    assert far.any()
    np.testing.assert_allclose(s.positions[far], plain.positions[far], atol=1e-12)
    assert (s.barycentrics >= 0).all()


def test_overlapping_layouts_are_counted_and_the_first_triangle_wins():
    res = 16
    uv, pos, nrm, _ = affine_quad()
    mirrored = uv.copy()
    mirrored[..., 0] = 1 - mirrored[..., 0]
    s = texel_samples(np.concatenate([uv, mirrored]), np.concatenate([pos, pos + 5]), np.concatenate([nrm, nrm]), res)
    assert s.overlapping == res * res and (s.triangles < 2).all() and s.outside == 0
    shifted = uv + [0.5, 0.0]  # half of the map twice
    s = texel_samples(np.concatenate([uv, shifted]), np.concatenate([pos, pos]), np.concatenate([nrm, nrm]), res)
    assert s.overlapping == res * res // 2 and s.outside == 2 and s.count == res * res


def test_degenerate_triangles_are_skipped_and_counted():
    uv, pos, nrm, _ = affine_quad((0.2, 0.2, 0.6, 0.6))
    line = np.array([[[0.7, 0.1], [0.8, 0.2], [0.9, 0.3]], [[0.5, 0.9], [0.5, 0.9], [0.5, 0.9]]])
    s = texel_samples(np.concatenate([uv, line]), np.concatenate([pos, pos]), np.concatenate([nrm, nrm]), 20)
    plain = texel_samples(uv, pos, nrm, 20)
    assert s.degenerate == 2 and np.array_equal(s.texels, plain.texels)
    assert (s.triangles < 2).all()


def test_average_is_the_mean_over_each_texels_samples():
    uv, pos, nrm, (o, a, b) = affine_quad((0.1, 0.2, 0.9, 0.7))
    s = texel_samples(uv, pos, nrm, 12)
    flat = s.positions.reshape(-1, 3)  # the bake points, sample-major
    values = np.concatenate([flat, np.repeat(np.arange(len(SAMPLE_OFFSETS)), s.count)[:, None]], axis=1)
    mean = s.average(values)
    assert mean.shape == (s.count, 4)
    np.testing.assert_allclose(mean[:, 3], np.mean(np.arange(len(SAMPLE_OFFSETS))))
    # Texels whose offset points are all on the rectangle: the samples are not moved, the mean of
    # the RGSS offsets is the centre, and the map is affine.
    row, col = np.divmod(s.texels, 12)
    centre = np.stack([(col + 0.5) / 12, (row + 0.5) / 12], -1)
    full = np.all((sample_uvs(s) >= [0.1, 0.2]) & (sample_uvs(s) <= [0.9, 0.7]), axis=(0, 2))
    np.testing.assert_allclose(mean[full, :3], (o + centre[:, :1] * a + centre[:, 1:] * b)[full], atol=1e-12)
    assert full.sum() > 0.5 * s.count


def test_image_scatters_values_into_the_covered_texels():
    uv, pos, nrm, _ = affine_quad((0.25, 0.5, 0.5, 1.0))
    s = texel_samples(uv, pos, nrm, 8)
    image = s.image(np.arange(s.count, dtype=float)[:, None] + 1)
    assert image.shape == (8, 8, 1)
    assert np.array_equal(np.flatnonzero(image[..., 0].ravel()), s.texels)
    assert image.reshape(-1)[s.texels[3]] == 4


def test_a_triangle_thinner_than_a_texel_covers_the_texels_it_crosses():
    res = 20
    uv = np.array([[[0.1, 0.5 + 0.45 / res], [0.9, 0.5 + 0.45 / res], [0.9, 0.5 + 0.55 / res]]])  # 0.1 texel high
    pos = np.concatenate([uv, np.zeros((1, 3, 1))], -1)
    s = texel_samples(uv, pos, np.tile([0.0, 0.0, 1.0], (1, 3, 1)), res)
    row, cols = int(0.5 * res), np.arange(int(0.1 * res), int(np.ceil(0.9 * res)))
    assert np.array_equal(s.texels, row * res + cols)
    # It lies between the offsets' rows (0.375, 0.625): every sample is snapped onto its closest point.
    tri = uv[0] * res
    suv = sample_uvs(s)
    for si in range(len(SAMPLE_OFFSETS)):
        for k in range(s.count):
            d, q, _b = point_triangle(suv[si, k] * res, tri)
            assert d > 0
            np.testing.assert_allclose(s.positions[si, k, :2] * res, q, atol=1e-9)


@pytest.mark.parametrize("threads", [1, 2])
def test_bands_and_threads_do_not_change_the_result(monkeypatch, threads):
    from prt_addon.core.transfer import texels

    uv, pos, nrm = random_layout(40, 6, 24)
    uv = np.concatenate([uv, uv[:5] + 0.01])  # some overlaps too
    pos, nrm = np.concatenate([pos, pos[:5]]), np.concatenate([nrm, nrm[:5]])
    whole = texel_samples(uv, pos, nrm, 24, threads=1)
    monkeypatch.setattr(texels, "BAND_PAIRS", 37)  # many bands, cut between rows
    banded = texel_samples(uv, pos, nrm, 24, threads=threads)
    assert whole.overlapping > 0
    for name in ("texels", "triangles", "barycentrics", "positions", "normals"):
        np.testing.assert_array_equal(getattr(banded, name), getattr(whole, name))
    assert (banded.overlapping, banded.outside, banded.degenerate) == (
        whole.overlapping,
        whole.outside,
        whole.degenerate,
    )
