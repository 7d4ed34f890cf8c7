"""The albedo at a bounce's hit on a textured triangle: the image at the hit's UV (identities on a
linear image, where a bilinear lookup is exact), through HitTransport's weights, mirrored too."""

import numpy as np

from prt_addon.core.transfer.bounce_hits import HitTransport
from prt_addon.core.transfer.hit_albedo import HitAlbedo

SIZE = 16


def _linear_image():
    """(SIZE, SIZE, 3): channel 0 = u, 1 = v, 2 = 0.25 + 0.5 u at the texel centres (row 0 at v = 0)."""
    centres = (np.arange(SIZE) + 0.5) / SIZE
    u, v = np.meshgrid(centres, centres)
    return np.stack([u, v, 0.25 + 0.5 * u], axis=-1)


UVS = np.array([[0.2, 0.2], [0.8, 0.25], [0.3, 0.75]])  # inside, over half a texel from the edges


def _expected(b1, b2):
    uv = UVS[0] * (1 - b1 - b2)[:, None] + UVS[1] * b1[:, None] + UVS[2] * b2[:, None]
    return np.stack([uv[:, 0], uv[:, 1], 0.25 + 0.5 * uv[:, 0]], axis=-1)


def test_lookup_at_the_barycentric_uv():
    rng = np.random.default_rng(1)
    b = rng.dirichlet([1, 1, 1], size=200)
    albedo = HitAlbedo(3)
    albedo.add([1], UVS[None], _linear_image())
    prims = np.array([0, 1, 2, 1] * 50)
    which, rho = albedo(prims, b[:, 1], b[:, 2])
    assert np.array_equal(which, prims == 1)
    np.testing.assert_allclose(rho, _expected(b[which, 1], b[which, 2]), atol=1e-6)


def _hits(orientation, from_below):
    """A unit right triangle a=(0,0,0), b=(1,0,0), c=(0,1,0) hit at known points by rays along -z
    (or +z from below): its weights / (scale cos) per hit, and the hits' (x, y)."""
    rng = np.random.default_rng(2)
    xy = rng.uniform(0.02, 0.98, size=(300, 2))
    xy = xy[xy.sum(axis=1) < 0.97]
    m = len(xy)
    z, d = (-1.0, 1.0) if from_below else (1.0, -1.0)
    origins = np.c_[xy, np.full(m, z)].astype(np.float32)
    dirs = np.tile([0.0, 0.0, d], (m, 1)).astype(np.float32)
    sink = HitTransport(
        [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], [[0, 1, 2]], [[0.5, 0.5, 0.5]], 64, orientation=orientation
    )
    albedo = HitAlbedo(1)
    albedo.add([0], UVS[None], _linear_image())
    sink.set_hit_albedo(albedo)
    cosines = np.full(m, 0.5, np.float32)
    _rows, _nodes, weights = sink(np.arange(m), np.zeros(m, np.int64), dirs, cosines, np.zeros(m, np.int32), origins)
    return weights / (sink.scale * 0.5), xy


def test_hit_weights_take_the_image_at_the_hit():
    weights, xy = _hits(None, from_below=False)
    assert len(weights) == len(xy)  # (every hit on the front face)
    np.testing.assert_allclose(weights, _expected(xy[:, 0], xy[:, 1]), rtol=1e-5, atol=1e-6)


def test_a_mirrored_triangle_keeps_its_uvs_where_they_were():
    # orientation -1: the sink stores (a, c, b) and the front face looks down; the UVs follow the corners.
    weights, xy = _hits([-1.0], from_below=True)
    assert len(weights) == len(xy)
    np.testing.assert_allclose(weights, _expected(xy[:, 0], xy[:, 1]), rtol=1e-5, atol=1e-6)


def test_instances_of_one_image_share_one_copy():
    image = _linear_image()
    albedo = HitAlbedo(4)
    albedo.add([0, 1], np.stack([UVS, UVS]), image, key=("image", 7))
    albedo.add([3], UVS[None], image, key=("image", 7))
    albedo.add([2], UVS[None], image)  # (no key: its own copy)
    assert len(albedo.images) == 2 and list(albedo.image_of) == [0, 0, 1, 0]
    which, rho = albedo(np.array([3, 2]), np.array([0.2, 0.2]), np.array([0.3, 0.3]))
    assert which.all() and np.allclose(rho[0], rho[1])


def test_the_node_sampling_reaches_the_lookup():
    """Clip: a hit whose UV falls outside the image reflects nothing; Repeat wraps it back in."""
    from prt_addon.core.transfer import image_sampling

    outside = np.array([[1.2, 0.5], [1.8, 0.5], [1.5, 0.9]])
    for extension, expected in ((image_sampling.CLIP, 0.0), (image_sampling.REPEAT, None)):
        albedo = HitAlbedo(1)
        albedo.add([0], outside[None], _linear_image(), sampling=(image_sampling.CLOSEST, extension))
        _which, rho = albedo(np.array([0]), np.array([0.25]), np.array([0.25]))
        uv = outside[0] * 0.5 + outside[1] * 0.25 + outside[2] * 0.25  # (1.425, 0.6): wraps to 0.425
        texel = (np.floor((uv - np.floor(uv)) * SIZE) + 0.5) / SIZE  # Closest: that texel's centre
        want = np.zeros(3) if expected is not None else [texel[0], texel[1], 0.25 + 0.5 * texel[0]]
        np.testing.assert_allclose(rho[0], want, atol=1e-6)
