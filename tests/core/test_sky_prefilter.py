"""The equirect GGX prefilter of the viewport's specular sky (core.ibl.sky_prefilter) against direct sums."""

import numpy as np
import pytest

from prt_addon.core.ibl import sky_prefilter
from prt_addon.core.sh import projection


def _image(seed, height=64, width=128):
    rng = np.random.default_rng(seed)
    img = rng.random((height, width, 3))
    img[40:44, 10:13] += 50.0  # a small bright source
    return img


@pytest.mark.parametrize("roughness", [0.2, 0.5, 1.0])
def test_fft_equals_the_direct_weighted_sum(roughness):
    img = _image(1)
    alpha = roughness * roughness
    out = sky_prefilter.prefilter_equirect(img, alpha)
    d = projection.pixel_directions(*img.shape[:2])
    omega = projection.pixel_solid_angles(*img.shape[:2])[:, None]
    for i, j in [(0, 0), (10, 77), (40, 11), (63, 127)]:
        w = sky_prefilter.ggx_lobe(d @ d[i, j], alpha) * omega
        assert np.allclose(out[i, j], (w[..., None] * img).sum((0, 1)) / w.sum(), rtol=1e-10)


def test_constant_sky_and_levels():
    levels = sky_prefilter.sky_levels(np.full((32, 64, 3), 0.7), width=32)
    assert levels.shape == (sky_prefilter.LEVELS, 16, 32, 3)
    assert np.allclose(levels, 0.7, atol=1e-12)
    assert np.allclose(sky_prefilter.constant_levels([0.7, 0.7, 0.7], 32), levels)


def test_levels_preserve_power_and_turn_with_the_image():
    """Each level keeps the sky's mean radiance to a few per cent (the lobe is normalised), and
    rolling the image's columns (a turn about Z) rolls every level the same."""
    img = _image(2)
    levels = sky_prefilter.sky_levels(img, width=64)
    omega = projection.pixel_solid_angles(32, 64)[:, None, None]
    power = [(lv * omega).sum() for lv in levels]
    assert np.allclose(power, power[0], rtol=0.05)
    turned = sky_prefilter.sky_levels(np.roll(img, 32, axis=1), width=64)
    assert np.allclose(turned, np.roll(levels, 16, axis=2), atol=1e-9)
    assert levels[-1].std() < 0.2 * levels[0].std()  # the roughest level is blurred


def test_wrapped_columns_make_a_clamped_lookup_wrap():
    """A clamp-to-edge linear lookup of the wrapped rows at x = (1 + u W) / (W + 2) gives the
    periodic linear interpolation of the row at u, across the seam too."""
    rng = np.random.default_rng(5)
    levels = rng.uniform(size=(2, 3, 8, 3))
    padded = sky_prefilter.wrapped_columns(levels)
    assert padded.shape == (2, 3, 10, 3)
    w = levels.shape[2]
    for u in (0.0, 0.01, 0.5, 0.99, 1.0):
        p = u * w - 0.5  # the row's own texel coordinate, wrapped
        i0 = int(np.floor(p))
        f = p - i0
        periodic = levels[:, :, i0 % w] * (1 - f) + levels[:, :, (i0 + 1) % w] * f
        x = (1 + u * w) / (w + 2) * (w + 2) - 0.5  # the padded row's texel coordinate
        j0 = int(np.clip(np.floor(x), 0, w + 1))
        g = x - j0
        clamped = padded[:, :, j0] * (1 - g) + padded[:, :, min(j0 + 1, w + 1)] * g
        assert np.allclose(clamped, periodic, atol=1e-12), u
