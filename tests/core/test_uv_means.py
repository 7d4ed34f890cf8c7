"""Image means over UV triangles against closed forms: a constant, a linear ramp, a red/blue image's halves, repeat;
the lookup's Closest and extensions against where Blender's Image Texture puts the image."""

import numpy as np
import pytest
from helpers import albedo_scenes

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


@pytest.mark.parametrize("extension", ["REPEAT", "EXTEND", "CLIP", "MIRROR"])
@pytest.mark.parametrize("interpolation", ["Linear", "Closest"])
def test_sample_image_follows_the_node_outside_0_1_and_at_edges(interpolation, extension):
    """The red/blue halves image with u from -1 to 2: where each extension puts the halves (more
    than a texel from every edge), and beside the red/blue edge bilinear weights or the nearer texel."""
    image = np.zeros((8, 8, 3))
    image[:, :4, 0], image[:, 4:, 2] = 1.0, 1.0
    u = np.linspace(-1.0, 2.0, 601)
    uv = np.c_[u, np.full_like(u, 0.4)]
    modes = (uv_means.CLOSEST if interpolation == "Closest" else uv_means.LINEAR, getattr(uv_means, extension))
    got = uv_means.sample_image(image, uv, np.float32, *modes)
    texel = 1.0 / 8.0
    clear = np.abs(u / 0.5 - np.round(u / 0.5)) * 0.5 > texel
    np.testing.assert_allclose(got[clear], albedo_scenes.expected_halves(u[clear], extension), atol=1e-6)
    edge = np.abs(u - 0.5) < texel / 2
    weight = np.clip(u[edge] * 8.0 - 3.5, 0.0, 1.0) if interpolation == "Linear" else (u[edge] >= 0.5) * 1.0
    np.testing.assert_allclose(got[edge], np.stack([1 - weight, 0 * weight, weight], axis=-1), atol=1e-5)
