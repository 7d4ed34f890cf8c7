"""Image lookups against where Blender's Image Texture puts the image: Repeat's wrap between the edge
texels, Closest and every extension outside 0..1 and at the red/blue edge of a halves image."""

import numpy as np
import pytest
from helpers import albedo_scenes

from prt_addon.core.transfer import image_sampling


def test_repeat_wraps_between_the_edge_texels():
    image = np.zeros((4, 8, 3))
    image[:, :4, 0] = 1.0  # left half red
    image[:, 4:, 2] = 1.0  # right half blue
    # Wrapping at u = 0: the lookup between texel 0 (red) and texel 7 (blue) mixes them.
    assert np.allclose(image_sampling.sample_image(image, [[0.0, 0.5]]), (0.5, 0.0, 0.5))


@pytest.mark.parametrize("extension", ["REPEAT", "EXTEND", "CLIP", "MIRROR"])
@pytest.mark.parametrize("interpolation", ["Linear", "Closest"])
def test_sample_image_follows_the_node_outside_0_1_and_at_edges(interpolation, extension):
    """The red/blue halves image with u from -1 to 2: where each extension puts the halves (more
    than a texel from every edge), and beside the red/blue edge bilinear weights or the nearer texel."""
    image = np.zeros((8, 8, 3))
    image[:, :4, 0], image[:, 4:, 2] = 1.0, 1.0
    u = np.linspace(-1.0, 2.0, 601)
    uv = np.c_[u, np.full_like(u, 0.4)]
    modes = (
        image_sampling.CLOSEST if interpolation == "Closest" else image_sampling.LINEAR,
        getattr(image_sampling, extension),
    )
    got = image_sampling.sample_image(image, uv, np.float32, *modes)
    texel = 1.0 / 8.0
    clear = np.abs(u / 0.5 - np.round(u / 0.5)) * 0.5 > texel
    np.testing.assert_allclose(got[clear], albedo_scenes.expected_halves(u[clear], extension), atol=1e-6)
    edge = np.abs(u - 0.5) < texel / 2
    weight = np.clip(u[edge] * 8.0 - 3.5, 0.0, 1.0) if interpolation == "Linear" else (u[edge] >= 0.5) * 1.0
    np.testing.assert_allclose(got[edge], np.stack([1 - weight, 0 * weight, weight], axis=-1), atol=1e-5)
