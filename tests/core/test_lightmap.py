"""Lightmap post-processing: bilinear lookup, gutter dilation, seam pairs and the seam fix (pure numpy)."""

import numpy as np
import pytest

from prt_addon.core.transfer.lightmap import bilinear, dilate, fix_seams, seam_pairs
from prt_addon.core.transfer.texels import texel_samples

# The cube [0, 1]^3, vertex 4x + 2y + z, unfolded as a cross in a 4 x 3 grid of cells (s, t):
#         [T]
#   [L] [F] [R] [Bk]
#         [D]
# Each face maps its cell to the cube; the net joins L-F, F-R, R-Bk, F-T and F-D.
FACES = {
    "L": ((0, 1), lambda s, t: (0 * s, 1 - s, t - 1)),
    "F": ((1, 1), lambda s, t: (s - 1, 0 * s, t - 1)),
    "R": ((2, 1), lambda s, t: (0 * s + 1, s - 2, t - 1)),
    "Bk": ((3, 1), lambda s, t: (4 - s, 0 * s + 1, t - 1)),
    "T": ((1, 2), lambda s, t: (s - 1, t - 2, 0 * s + 1)),
    "D": ((1, 0), lambda s, t: (s - 1, 1 - t, 0 * s)),
}
JOINS = {(0, 1), (4, 5), (6, 7), (1, 5), (0, 4)}  # the cube edges the net keeps joined
CUBE_EDGES = {(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1}
CELL = 0.22  # the net's cell in UV: 4 x 0.22 = 0.88 wide
MARGIN = 0.06


def cube_net():
    """(corner vertices (12, 3), uvs (12, 3, 2), positions (12, 3, 3), normals (12, 3, 3))."""
    verts, uvs, pos = [], [], []
    for (col, row), fold in FACES.values():
        square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float) + [col, row]
        for tri in ([0, 1, 2], [0, 2, 3]):
            st = square[tri]
            p = np.stack(fold(st[:, 0], st[:, 1]), axis=1)
            pos.append(p)
            verts.append((4 * p[:, 0] + 2 * p[:, 1] + p[:, 2]).round().astype(int))
            uvs.append(MARGIN + CELL * st)
    pos = np.array(pos)
    centre = pos.mean(axis=1, keepdims=True) - 0.5
    normals = np.repeat(np.sign(centre) * (np.abs(centre) > 0.4), 3, axis=1)  # flat faces
    return np.array(verts), np.array(uvs), pos, normals


def f_smooth(p):
    return np.stack(
        [1 + 0.3 * p[..., 0] - 0.2 * p[..., 1] + 0.1 * p[..., 2], 0.5 + 0.2 * np.sin(2 * p[..., 0] + p[..., 2])], -1
    )


def test_bilinear_is_exact_on_affine_images_with_clamp_to_edge():
    h, w = 6, 9
    rows, cols = np.indices((h, w))
    image = np.stack([0.5 + 2.0 * cols - 0.75 * rows, np.ones((h, w))], -1)  # affine in the centres
    rng = np.random.default_rng(0)
    uv = rng.uniform(-0.2, 1.2, (200, 2))
    x = np.clip(uv[:, 0] * w - 0.5, 0, w - 1)  # clamp-to-edge: the centre coordinate clamped
    y = np.clip(uv[:, 1] * h - 0.5, 0, h - 1)
    np.testing.assert_allclose(bilinear(image, uv), np.stack([0.5 + 2.0 * x - 0.75 * y, np.ones(200)], 1), atol=1e-12)
    centres = np.stack([(cols.ravel() + 0.5) / w, (rows.ravel() + 0.5) / h], 1)
    noise = rng.normal(size=(h, w, 3))
    np.testing.assert_allclose(bilinear(noise, centres), noise.reshape(-1, 3), atol=1e-12)


def chebyshev_distance(mask):
    """Each texel's Chebyshev distance (in texels) to the nearest True texel, by brute force."""
    rows, cols = np.indices(mask.shape)
    r, c = np.nonzero(mask)
    d = np.maximum(np.abs(rows.ravel()[:, None] - r), np.abs(cols.ravel()[:, None] - c))
    return d.min(axis=1).reshape(mask.shape)


@pytest.mark.parametrize("passes", [1, 4, 6])
def test_dilate_a_constant_disc_fills_a_gutter_of_passes_texels_with_the_constant(passes):
    res = 48
    rows, cols = np.indices((res, res))
    disc = (rows - 20.3) ** 2 + (cols - 25.1) ** 2 < 9.5**2
    rng = np.random.default_rng(1)
    image = np.where(disc[..., None], 3.7, rng.normal(size=(res, res, 2)))  # garbage outside
    out = dilate(image, disc, passes=passes, rest="zero")
    gutter = chebyshev_distance(disc) <= passes
    np.testing.assert_allclose(out[gutter], 3.7, rtol=1e-12)
    assert (out[~gutter] == 0).all()
    np.testing.assert_array_equal(out[disc], image[disc])
    np.testing.assert_allclose(dilate(image, disc, passes=passes), 3.7, rtol=1e-12)  # rest="nearest"


def test_dilate_gutter_is_the_mean_of_the_filled_neighbours():
    image = np.zeros((5, 5, 1))
    covered = np.zeros((5, 5), bool)
    covered[2, 1], covered[2, 3] = True, True
    image[2, 1], image[2, 3] = 1.0, 3.0
    out = dilate(image, covered, passes=1, rest="zero")[..., 0]
    assert out[2, 2] == 2.0 and out[1, 2] == 2.0 and out[2, 0] == 1.0 and out[1, 4] == 3.0
    assert out[0, 2] == 0.0


@pytest.mark.parametrize(
    ("seed", "shape", "count", "passes"),
    [(2, (40, 40), 15, 0), (3, (30, 53), 4, 0), (4, (64, 48), 40, 2), (5, (17, 9), 1, 1)],
)
def test_dilate_beyond_the_gutter_takes_the_nearest_filled_value(seed, shape, count, passes):
    h, w = shape
    rng = np.random.default_rng(seed)
    seeds = np.zeros(shape, bool)
    seeds.ravel()[rng.choice(h * w, count, replace=False)] = True
    image = np.where(seeds, np.arange(h * w).reshape(shape), -1.0)
    filled = chebyshev_distance(seeds) <= passes  # the gutter, which holds means of seeds' indices
    out = dilate(image, seeds, passes=passes)
    beyond = ~filled
    rows, cols = np.indices(shape)
    fr, fc = np.nonzero(filled)
    d2 = (rows[beyond][:, None] - fr) ** 2 + (cols[beyond][:, None] - fc) ** 2
    # The value taken is that of a filled texel at the least distance (ties either way).
    nearest_values = np.where(d2 == d2.min(axis=1, keepdims=True), out[fr, fc][None, :], np.nan)
    assert np.isclose(nearest_values, out[beyond][:, None]).any(axis=1).all()


def test_seam_pairs_of_a_cube_cross_are_its_seven_cut_edges():
    verts, uvs, _pos, _n = cube_net()
    seams = seam_pairs(verts, uvs)
    cut = CUBE_EDGES - JOINS
    assert len(CUBE_EDGES) == 12 and len(cut) == 7
    assert {tuple(e) for e in seams.vertices} == cut and len(seams) == 7
    # Both sides are the same 3D edge: each side's UV maps through its own triangle to the ends.
    for e in range(len(seams)):
        for side, uv in ((0, seams.uv_a[e]), (1, seams.uv_b[e])):
            t = seams.triangles[e, side]
            for end in range(2):
                corner = np.flatnonzero(verts[t] == seams.vertices[e, end])[0]
                np.testing.assert_array_equal(uv[end], uvs[t, corner])
    assert len(seam_pairs(verts, uvs + 0.0)) == 7
    # Welded in UV too (one UV per vertex): no seams; an open edge is no seam.
    welded = np.stack([verts / 8.0, verts / 16.0], -1)
    assert len(seam_pairs(verts, welded)) == 0
    assert len(seam_pairs(verts[:1], uvs[:1])) == 0


def seam_image(res, seed, noise):
    verts, uvs, pos, nrm = cube_net()
    s = texel_samples(uvs, pos, nrm, res, offsets=np.array([[0.5, 0.5]]))
    rng = np.random.default_rng(seed)
    values = f_smooth(s.positions[0]) + noise * rng.normal(size=(s.count, 2))
    covered = s.covered()
    image = dilate(s.image(values), covered, passes=2)
    return verts, uvs, image, covered


def seam_gap(image, seams, res):
    a, b, _ = seams.samples(res)
    return bilinear(image, a) - bilinear(image, b), a, b


def test_fix_seams_makes_both_sides_agree_and_leaves_the_rest():
    res, noise = 64, 0.05
    verts, uvs, image, covered = seam_image(res, 3, noise)
    seams = seam_pairs(verts, uvs)
    before, a, b = seam_gap(image, seams, res)
    out = fix_seams(image, seams, covered)
    after, _, _ = seam_gap(out, seams, res)
    assert np.sqrt(np.mean(before**2)) > 0.5 * noise
    assert np.sqrt(np.mean(after**2)) < 0.1 * noise
    # Texels outside every sample's bilinear footprint (centre within one texel in x and y of the
    # clamped sample point) are unchanged, bit for bit.
    rows, cols = np.indices((res, res))
    footprint = np.zeros((res, res), bool)
    for p in np.concatenate([a, b]):
        x, y = np.clip(p * res - 0.5, 0, res - 1)
        footprint |= (np.abs(cols - x) < 1) & (np.abs(rows - y) < 1)
    np.testing.assert_array_equal(out[~footprint], image[~footprint])
    assert (out[footprint] != image[footprint]).any(axis=-1).mean() > 0.9
    # The values near the seams stay close to the data (the smooth function).
    assert np.abs(out - image)[footprint & covered].max() < 6 * noise


def test_fix_seams_is_the_least_squares_solution():
    """Against a dense solve of the normal equations built from bilinear() itself."""
    res, weight, gutter = 16, 3.0, 0.2
    verts, uvs, image, covered = seam_image(res, 4, 0.1)
    seams = seam_pairs(verts, uvs)
    a, b, _ = seams.samples(res)
    # Row k of B: bilinear_a - bilinear_b of each texel's unit image.
    unit = np.eye(res * res).reshape(res, res, res * res)
    rows_b = bilinear(unit, a) - bilinear(unit, b)
    d = np.where(covered.ravel(), 1.0, gutter)
    x0 = image.reshape(-1, 2)
    x = np.linalg.solve(np.diag(d) + weight * rows_b.T @ rows_b, d[:, None] * x0)
    out = fix_seams(image, seams, covered, weight=weight, gutter_weight=gutter, tolerance=1e-13)
    np.testing.assert_allclose(out.reshape(-1, 2), x, atol=1e-8)


def test_a_constant_image_is_a_fixed_point():
    res = 32
    verts, uvs, _image, covered = seam_image(res, 5, 0.0)
    image = np.full((res, res, 3), 0.625)
    np.testing.assert_allclose(fix_seams(image, seam_pairs(verts, uvs), covered), image, atol=1e-14)
