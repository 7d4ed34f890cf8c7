"""The truncation figures reported by Project World mean what they say."""

import numpy as np
import pytest

from prt_addon.core.sh import analytic, basis as sh, directions, projection, resample


def sunny_image(height=128, width=256):
    dirs = projection.pixel_directions(height, width)
    sun = np.array([0.5, -0.3, 0.81]) / np.linalg.norm([0.5, -0.3, 0.81])
    sky = 0.5 + 0.5 * np.clip(dirs[..., 2], 0, None)
    image = np.where(dirs @ sun > np.cos(np.radians(3.0)), 2e3, sky)
    return image[..., None] * np.array([1.0, 0.9, 0.8])


@pytest.fixture(scope="module")
def brute_force():
    image = sunny_image()
    height, width = image.shape[:2]
    dirs = projection.pixel_directions(height, width).reshape(-1, 3)
    weights = np.repeat(projection.pixel_solid_angles(height, width), width)
    lum = image.reshape(-1, 3) @ resample.LUMINANCE
    normals = directions.fibonacci_directions(8192)
    truth = np.maximum(0.0, normals @ dirs.T) @ (lum * weights) / np.pi
    return image, normals, truth, float(np.sum(lum**2 * weights))


@pytest.mark.parametrize("order", [2, 3, 4, 8])
def test_diffuse_truncation_is_the_squared_relative_error_of_diffuse_shading(order, brute_force):
    """Parseval: over all normals, ||D - D_n||^2 / ||D||^2 equals the energy fraction beyond n.

    Checked against brute force: D(n) = sum over pixels of L max(0, n.w)/pi dOmega at 8192
    Fibonacci normals (their mean is an integral over the sphere to ~1e-3 relative).
    """
    image, normals, truth, radiance_energy = brute_force
    coeffs, _ = projection.project_equirect(image, order)
    shaded = sh.evaluate(sh.convolve_zonal(coeffs, analytic.clamped_cosine_zonal(order)), normals) @ resample.LUMINANCE
    measured = np.mean((shaded - truth) ** 2) / np.mean(truth**2)

    reference, _ = projection.project_equirect(image, resample.DIFFUSE_REFERENCE_ORDER)
    reported = resample.diffuse_truncation_fraction(reference, order)
    assert reported == pytest.approx(measured, rel=0.05)
    # ... while the radiance truncation of the same sunny world is near total.
    radiance = resample.truncation_fraction(coeffs, radiance_energy)
    assert radiance > 0.5
    assert reported < radiance / 5
