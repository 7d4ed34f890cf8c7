"""Image means over UV triangles against closed forms: a constant, a linear ramp, a red/blue image's halves, repeat."""

import numpy as np

from prt_addon.core.transfer import uv_means


def test_centroids_are_a_midpoint_rule():
    for n in (1, 2, 4, 7):
        bary = uv_means.centroid_barycentrics(n)
        assert bary.shape == (n * n, 3) and np.allclose(bary.sum(axis=1), 1.0) and (bary > 0).all()
        assert np.allclose(bary.mean(axis=0), 1 / 3)  # the centroid: exact for linear functions


def test_linear_ramp_mean_is_the_value_at_the_centroid():
    width = 64
    ramp = ((np.arange(width) + 0.5) / width)[None, :, None].repeat(8, axis=0)  # value = u at texel centres
    tri = np.array([[[0.2, 0.1], [0.7, 0.3], [0.4, 0.9]]])
    assert np.allclose(uv_means.triangle_means(ramp, tri), (0.2 + 0.7 + 0.4) / 3)


def test_halves_and_repeat():
    image = np.zeros((4, 8, 3))
    image[:, :4, 0] = 1.0  # left half red
    image[:, 4:, 2] = 1.0  # right half blue
    left = np.array([[[0.1, 0.1], [0.35, 0.1], [0.1, 0.9]]])
    assert np.allclose(uv_means.triangle_means(image, left), (1.0, 0.0, 0.0))
    assert np.allclose(uv_means.triangle_means(image, left + [3.0, -2.0]), (1.0, 0.0, 0.0))  # Repeat
    # A square over the whole image (two triangles): the image's mean.
    square = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], dtype=float)
    assert np.allclose(uv_means.triangle_means(image, square, n=8).mean(axis=0), (0.5, 0.0, 0.5))
    # Wrapping at u = 0: the lookup between texel 0 (red) and texel 7 (blue) mixes them.
    assert np.allclose(uv_means.bilinear_repeat(image, [[0.0, 0.5]]), (0.5, 0.0, 0.5))
