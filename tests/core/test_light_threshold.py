"""The automatic threshold rule T = max(MEAN_FACTOR x mean, T_compact) against direct sums."""

import numpy as np
import pytest
from helpers.sky import sky_with_discs, unit

from prt_addon.core.lights import extraction as lights
from prt_addon.core.sh.projection import pixel_solid_angles

HEIGHT, WIDTH = 256, 512


def mean_luminance(image):
    """Solid-angle-weighted mean luminance, summed texel by texel."""
    solid = np.broadcast_to(pixel_solid_angles(*image.shape[:2])[:, None], image.shape[:2])
    return float((image.astype(np.float64) @ lights.LUMA * solid).sum() / (4.0 * np.pi))


@pytest.mark.parametrize("factor", [None, 2.0, 8.0])
def test_a_small_bright_disc_sets_no_compact_limit(factor):
    image = sky_with_discs([(unit(30.0, 20.0), np.radians(2.0), 1000.0)], height=HEIGHT, width=WIDTH)
    kwargs = {} if factor is None else {"mean_factor": factor}
    expected = (lights.MEAN_FACTOR if factor is None else factor) * mean_luminance(image)
    assert lights.auto_threshold(image, **kwargs) == pytest.approx(expected, rel=1e-12)


def test_the_compact_term_keeps_the_bright_texels_within_the_budget():
    """A 30 degree cap of 50 on a sky of 1 covers 6.7 % of the sphere: within the rule's 10 %
    budget it is split at MEAN_FACTOR x mean; with a 1 % budget T rises to the cap's own value
    (no light)."""
    image = sky_with_discs([(unit(-60.0, 30.0), np.radians(30.0), 50.0)], height=HEIGHT, width=WIDTH)
    mean = mean_luminance(image)
    assert lights.MEAN_FACTOR * mean < 50.0
    assert lights.COMPACT_FRACTION == 0.1
    loose = lights.auto_threshold(image)
    assert loose == pytest.approx(lights.MEAN_FACTOR * mean, rel=1e-12)
    assert len(lights.extract_lights(image, loose)[1]) == 1
    strict = lights.auto_threshold(image, compact_fraction=0.01)
    assert strict == pytest.approx(50.0, rel=1e-6)
    lum = image.astype(np.float64) @ lights.LUMA
    solid = np.broadcast_to(pixel_solid_angles(HEIGHT, WIDTH)[:, None], lum.shape)
    assert solid[lum > strict].sum() <= 0.01 * 4.0 * np.pi
    assert lights.extract_lights(image, strict)[1] == []
