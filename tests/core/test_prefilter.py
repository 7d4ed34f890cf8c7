"""The GGX cube-map prefilter and the RGBD PNG encoding (core.ibl.prefilter, core.ibl.rgbd_png) against independent expectations."""

import numpy as np
import pytest
from helpers.png import _decode_png
from helpers.sampling import random_directions

from prt_addon.core.ibl import prefilter, rgbd_png
from prt_addon.core.sh import basis as sh, directions, projection


def test_face_directions_by_hand():
    """Texel centres of a 2x2 cube: WebGL's face table, rows by t, columns by s."""
    d = prefilter.face_directions(2)
    unit = lambda v: np.array(v, dtype=np.float64) / np.linalg.norm(v)
    # face, row (t), column (s) -> direction, from the table (s, t = -0.5 or 0.5)
    cases = {
        (0, 0, 0): (1, 0.5, 0.5),  # +X: (1, -t, -s)
        (1, 0, 1): (-1, 0.5, 0.5),  # -X: (-1, -t, s)
        (2, 0, 1): (0.5, 1, -0.5),  # +Y: (s, 1, t)
        (3, 1, 0): (-0.5, -1, -0.5),  # -Y: (s, -1, -t)
        (4, 1, 1): (0.5, -0.5, 1),  # +Z: (s, -t, 1)
        (5, 0, 0): (0.5, 0.5, -1),  # -Z: (-s, -t, -1)
    }
    for (f, j, i), v in cases.items():
        assert np.allclose(d[f, j, i], unit(v)), (f, j, i, d[f, j, i])
    assert len(prefilter.FACE_NAMES) == 6
    for f, name in enumerate(prefilter.FACE_NAMES):  # each face is named after the axis it looks along
        axis = np.zeros(3)
        axis["XYZ".index(name[1])] = 1.0 if name[0] == "+" else -1.0
        assert np.allclose(unit(d[f].reshape(-1, 3).mean(axis=0)), axis), (f, name)


@pytest.mark.parametrize("size", [1, 2, 8, 64])
def test_direction_to_texel_inverts_face_directions(size):
    d = prefilter.face_directions(size)
    face, row, column = prefilter.direction_to_texel(d, size)
    idx = np.indices((6, size, size))
    assert (face == idx[0]).all()
    assert (row == idx[1]).all()
    assert (column == idx[2]).all()


def test_texel_solid_angles():
    omega = prefilter.texel_solid_angles(16)
    assert 6 * omega.sum() == pytest.approx(4 * np.pi, rel=1e-12)
    # texel (3, 5) by a fine midpoint rule of the Jacobian (1 + s^2 + t^2)^(-3/2) ds dt
    fine = 200
    s = -1 + (3 + (np.arange(fine) + 0.5) / fine) * 2 / 16
    t = -1 + (5 + (np.arange(fine) + 0.5) / fine) * 2 / 16
    ss, tt = np.meshgrid(s, t, indexing="ij")
    numeric = ((1 + ss**2 + tt**2) ** -1.5).sum() * (2 / 16 / fine) ** 2
    assert omega[3, 5] == pytest.approx(numeric, rel=1e-5)


def test_ggx_weight_is_the_textbook_lobe():
    """max(n.l, 0) D(h) from explicit half vectors equals the weight written in n.l alone."""
    n = random_directions(500, 2)
    lv = random_directions(500, 3)
    for alpha in (0.02, 0.3, 1.0):
        h = n + lv
        h /= np.linalg.norm(h, axis=1, keepdims=True)
        nh = np.einsum("ij,ij->i", n, h)
        d = alpha**2 / (np.pi * (nh**2 * (alpha**2 - 1) + 1) ** 2)
        c = np.einsum("ij,ij->i", n, lv)
        expected = np.maximum(c, 0) * d
        got = prefilter.ggx_weight(c.astype(np.float32), alpha) * alpha**2 / np.pi
        assert np.allclose(got, expected, rtol=2e-4, atol=1e-6 * expected.max()), alpha


def test_babylon_alphas():
    """Mip k of a 128 chain: alpha = 2^k / 128 (0 at mip 0), i.e. Babylon's lod = log2(N0 alpha)."""
    a = prefilter.babylon_alphas(128)
    assert len(a) == 8
    assert a[0] == 0.0
    assert a[-1] == 1.0
    assert np.allclose(np.log2(128 * a[1:]), np.arange(1, 8))
    with pytest.raises(ValueError, match="the cube map size must be a power of two, got 96"):
        prefilter.babylon_alphas(96)


def test_constant_environment_stays_constant_at_every_mip():
    cube = np.broadcast_to(np.array([0.3, 1.0, 7.0]), (6, 32, 32, 3)).copy()
    for mip in prefilter.prefilter_mips(cube):
        assert np.allclose(mip, [0.3, 1.0, 7.0], rtol=1e-5)


def test_mip0_texel_is_the_equirect_pixel_in_its_direction():
    """An image whose pixels hold their own centre directions: each mip-0 texel (one lookup,
    supersample 1) holds a direction within a pixel of the texel's, through a rotation."""
    height, width = 32, 64
    image = 0.5 * (projection.pixel_directions(height, width) + 1.0)  # non-negative, as radiance
    q = directions.random_rotation(np.random.default_rng(4))
    cube = 2.0 * prefilter.radiance_cube(image, 16, to_image=q, supersample=1) - 1.0
    expected = prefilter.face_directions(16) @ q.T  # the image direction each texel looks up
    err = np.degrees(np.arccos(np.clip(np.einsum("...i,...i", cube, expected), -1, 1)))
    assert err.max() < 360.0 / width, err.max()  # within one pixel (5.6 degrees at the equator)
    # and a mirrored lookup would be far off
    mirrored = 2.0 * prefilter.radiance_cube(image, 16, to_image=q @ np.diag([-1.0, 1.0, 1.0]), supersample=1) - 1.0
    assert np.einsum("...i,...i", mirrored, expected).min() < 0.0


def test_roughness_one_is_the_cosine_average():
    """At alpha = 1, D is constant: the prefilter is the cosine-weighted mean, E(n) / pi for a
    band-limited (order 3) environment, in closed form A_l c_lm."""
    rng = np.random.default_rng(7)
    coeffs = 0.3 * rng.normal(size=(9, 3))
    coeffs[0] = 3.0
    cube = prefilter.cube_from_function(lambda d: sh.sh_basis(d.reshape(-1, 3), 3) @ coeffs, 32)
    out = prefilter.prefilter_level(cube, 4, 1.0)
    a = np.array([np.pi] + [2 * np.pi / 3] * 3 + [np.pi / 4] * 5)
    expected = sh.sh_basis(prefilter.face_directions(4).reshape(-1, 3), 3) @ (a[:, None] * coeffs) / np.pi
    expected = expected.reshape(out.shape)
    assert np.abs(out - expected).max() / expected.mean() < 1e-3  # measured 1.5e-4


def _blob(d):
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    return (0.2 + 5.0 * np.exp((d @ axis - 1.0) / 0.02))[..., None] * np.array([1.0, 0.5, 0.25])


@pytest.mark.parametrize("k", [1, 2, 3, 4, 5, 6])
def test_lobe_against_an_independent_quadrature(k):
    """Mip k of a 64 chain against the GGX integral by a 400k-point Fibonacci quadrature of the
    analytic environment (not of the cube), at random directions."""
    base = 64
    mips = prefilter.prefilter_mips(prefilter.cube_from_function(_blob, base, supersample=4))
    alpha = prefilter.babylon_alphas(base)[k]
    points = directions.fibonacci_directions(400_000)
    values = _blob(points)
    size = base >> k
    dirs = prefilter.face_directions(size).reshape(-1, 3)
    pick = np.random.default_rng(k).choice(dirs.shape[0], size=min(40, dirs.shape[0]), replace=False)
    c = dirs[pick] @ points.T
    w = np.maximum(c, 0) / (alpha**2 + (1 - c) * (1 - alpha**2) / 2) ** 2
    expected = (w @ values) / w.sum(axis=1, keepdims=True)
    got = mips[k].reshape(-1, 3)[pick]
    err = np.abs(got - expected).max() / expected.max()
    assert err < 0.01, (k, err)  # measured 0.02-0.4 % of the peak


def test_bright_spot_lands_at_its_direction():
    """A narrow bright source: the brightest texel of every mip is the one holding its direction."""
    base = 32
    mips = prefilter.prefilter_mips(prefilter.cube_from_function(_blob, base, supersample=4))
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    for mip in mips[:-2]:  # the 2x2 and 1x1 faces are too coarse to tell
        size = mip.shape[1]
        where = np.unravel_index(np.argmax(mip[..., 0]), mip.shape[:3])
        assert tuple(int(v) for v in where) == tuple(int(v) for v in prefilter.direction_to_texel(axis, size))


def test_rgbd_round_trip_and_range():
    v = np.geomspace(1e-2, 250.0, 2000)
    rgb = np.stack([v, 0.5 * v, 0.25 * v], axis=1)
    back = rgbd_png.rgbd_decode(rgbd_png.rgbd_encode(rgb))
    # the brightest channel keeps 8-bit gamma precision; the darker ones are relative to it
    assert (np.abs(back[:, 0] - v) / v).max() < 0.04
    assert (np.abs(back - rgb).max(axis=1) / v).max() < 0.04
    enc = rgbd_png.rgbd_encode([[0.5, 0.2, 0.1], [1000.0, 1.0, 0.0], [-1.0, np.nan, np.inf]])
    assert enc[0, 3] == 255  # values up to 1: D = 1
    assert enc[1, 0] == 255
    assert enc[1, 3] == 1
    assert rgbd_png.rgbd_decode(enc[1])[0] == pytest.approx(255.0)  # clipped to the largest value
    assert tuple(enc[2, :3]) == (0, 0, 0)


def test_png_round_trip():
    rgba = np.random.default_rng(3).integers(0, 256, size=(7, 5, 4), dtype=np.uint8)
    assert np.array_equal(_decode_png(rgbd_png.png_bytes(rgba)), rgba)
    with pytest.raises(ValueError, match=r"expected an \(H, W, 4\) image, got shape \(4, 4, 3\)"):
        rgbd_png.png_bytes(np.zeros((4, 4, 3), np.uint8))


@pytest.mark.parametrize("size", [1, 2, 4, 8])
def test_symmetry_indices_move_texels_with_their_directions(size):
    d = prefilter.face_directions(size).reshape(-1, 3)
    groups = prefilter.cube_symmetries()
    assert len(groups) == 48
    assert len({g.tobytes() for g in groups}) == 48
    for g in groups:
        idx = prefilter.symmetry_indices(g, size)
        assert np.allclose(d[idx], d @ g.T)
    covered = np.zeros(6 * size * size, bool)
    for g in groups:
        covered[prefilter.symmetry_indices(g, size).reshape(6, -1)[0][prefilter.fundamental_texels(size)]] = True
    assert covered.all()
