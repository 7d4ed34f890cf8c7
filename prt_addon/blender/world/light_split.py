"""The light split of a world image: its checks, the extraction, the figures shown, the storage.

The maths is prt_addon.core.lights.extraction; docs/world.md ("Light split") explains what is stored.
"""

import dataclasses

import numpy as np

from ...core.lights import extraction as core_lights, samples as core_samples
from ...core.sh.projection import ROW_BLOCK, as_rgb_image, pixel_solid_angles
from .nodes import WorldError

LIGHTS_KEY = "prt_world_lights"  # image-frame lights, flat (core.lights.extraction.lights_to_array)
SAMPLES_KEY = "prt_world_light_samples"  # their samples (core.lights.samples.samples_to_array)


def check_split_settings(threshold, max_lights):
    """(threshold or None for automatic, max_lights) after checking them; raises WorldError."""
    if isinstance(threshold, bool) or not isinstance(threshold, (int, float, np.integer, np.floating)):
        raise WorldError(f"the light threshold must be a number (0: automatic), got {threshold!r}")
    if not np.isfinite(threshold) or threshold < 0.0:
        raise WorldError(f"the light threshold must be finite and >= 0 (0: automatic), got {threshold!r}")
    if (
        isinstance(max_lights, bool)
        or not isinstance(max_lights, (int, np.integer))
        or not 0 <= max_lights <= core_lights.MAX_LIGHTS
    ):
        raise WorldError(
            f"the number of lights must be an integer from 0 to {core_lights.MAX_LIGHTS}, got {max_lights!r}"
        )
    return (float(threshold) if threshold > 0.0 else None), int(max_lights)


def _may_have_lights(rgb, threshold):
    """False when no texel can pass the threshold, found in one pass of ROW_BLOCK rows without
    copying the image: the automatic threshold is at least MEAN_FACTOR times the mean
    luminance, so an image whose brightest texel is below that has no light (a one-colour image,
    or any image too big to copy for nothing)."""
    height, width, _ = rgb.shape
    solid = pixel_solid_angles(height, width)
    brightest, power = 0.0, 0.0
    for start in range(0, height, ROW_BLOCK):
        values = np.fmax(rgb[start : start + ROW_BLOCK].astype(np.float64), 0.0)  # NaN -> 0
        values[np.isinf(values)] = 0.0
        lum = values @ core_lights.LUMA
        brightest = max(brightest, float(lum.max()))
        power += float(lum.sum(axis=1) @ solid[start : start + ROW_BLOCK])
    if threshold is not None:
        return brightest > threshold
    return brightest > core_lights.MEAN_FACTOR * power / (4.0 * np.pi)


def split(pixels, threshold, max_lights):
    """(residual or the pixels themselves, [Light]) of a full-resolution equirect image."""
    if max_lights == 0 or not _may_have_lights(as_rgb_image(pixels), threshold):
        return pixels, []
    try:
        return core_lights.extract_lights(pixels, threshold, max_lights)
    except ValueError as error:
        raise WorldError(f"the light split failed: {error}") from None


def scaled(lights, strength):
    """The lights with their power times the Background strength (zero-power lights dropped)."""
    out = []
    for light in lights:
        power = light.power * strength
        if np.any(power > 0.0):
            out.append(dataclasses.replace(light, power=power))
    return out


def share(lights, image_coeffs):
    """Fraction of the world's luminance power held by the lights: the sky's power is
    sqrt(4 pi) c_0 (c_0 = integral f y_0, y_0 = 1 / sqrt(4 pi))."""
    in_lights = sum(light.luminance for light in lights)
    sky = float(np.sqrt(4.0 * np.pi) * image_coeffs[0] @ core_lights.LUMA)
    total = in_lights + sky
    return in_lights / total if total > 0.0 else 0.0


def elevation(light, rotation):
    """Elevation (radians) of an image-frame light in the world turned by the 3x3 rotation."""
    return float(np.arcsin(np.clip((np.asarray(rotation) @ light.direction)[2], -1.0, 1.0)))


def store(scene, lights):
    """Write the image-frame lights and their samples next to the SH (the keys are removed when
    there are none)."""
    if lights:
        scene[LIGHTS_KEY] = core_lights.lights_to_array(lights)
        scene[SAMPLES_KEY] = core_samples.samples_to_array(lights)
    else:
        for key in (LIGHTS_KEY, SAMPLES_KEY):
            if key in scene:
                del scene[key]


def stored(scene):
    """[Light] stored on the scene in the image frame; [] when none (or an older projection).
    Lights stored without samples (before they existed), or with unreadable ones, are discs."""
    values, samples = (_floats(scene.get(key)) for key in (LIGHTS_KEY, SAMPLES_KEY))
    if values is None:
        return []
    for with_samples in ((samples,) if samples is not None else ()) + (None,):
        try:
            return core_lights.lights_from_array(values, with_samples)
        except ValueError:
            continue
    return []


def _floats(data):
    if data is None:
        return None
    return data.to_list() if hasattr(data, "to_list") else list(data)


def summary(settings):
    """The panel's lines about the split (each short enough for the default sidebar width)."""
    if not settings.stored_split:
        return ["Light split off: no lights"]
    if settings.light_count == 0:
        return ["No compact bright source:", "no lights"]
    count = settings.light_count
    word = "light" if count == 1 else "lights"
    degrees = np.degrees(settings.strongest_elevation)
    where = f"{degrees:.0f}\u00b0 up" if degrees >= 0.0 else f"{-degrees:.0f}\u00b0 down"
    return [f"{count} {word}: {100.0 * settings.light_share:.0f} % of the light,", f"strongest {where}"]
