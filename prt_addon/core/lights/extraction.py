"""Analytic lights split off the compact bright sources of an equirectangular world image.

SH of any practical order cannot hold a sun: texels brighter than a luminance threshold T are
clamped to T (hue kept), their excess becomes a few disc lights and the clamped image (residual)
goes to the SH projection; residual + lights is exactly the input (docs/lights.md).

Pixels are (H, W, C) linear RGB laid out like `projection.project_equirect` expects
(row 0 is the nadir, +X the image centre). Luminance is Rec.709: 0.2126 R + 0.7152 G + 0.0722 B.
A light's `power` is the RGB excess radiance integrated over solid angle, so a surface facing it
receives the irradiance `power` and, in the project's units (transfer includes 1/pi), shows the
radiance power / pi * max(0, n . s) * V. Directions are in the image (world) frame; after a world
rotation R (direction in world = R @ direction in image frame) use `rotate_lights`. Each
extracted light also keeps power-weighted sample directions over its own texels
(core.lights.samples), which its shading uses instead of the disc.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from ..sh.projection import as_rgb_image, column_azimuths, row_elevations
from .samples import SAMPLES_PER_LIGHT, median_angle, region_samples, samples_from_array

LUMA = np.array([0.2126, 0.7152, 0.0722])
MAX_LIGHTS = 8
MEAN_FACTOR = 3.0  # threshold rule: see auto_threshold
COMPACT_FRACTION = 0.10
MIN_SHARE = 0.005  # regions with less of the world's luminance power stay in the residual
FLOATS_PER_LIGHT = 7  # direction 3, power 3, angle 1
LUMINANCE_ROWS = 16  # rows converted to float64 at a time (stays in cache: measured fastest)


@dataclass
class Light:
    """A light: unit direction, RGB power (integral of excess radiance), angular radius of the
    disc with the same mean cosine; optionally samples (k, 3) unit directions with weights (k,)
    summing to 1 (core.lights.samples), which the shading uses instead of the disc when given, and
    shadow_angle, the radius the viewport's shadow filter uses (None: angle)."""

    direction: np.ndarray
    power: np.ndarray
    angle: float
    solid_angle: float = 0.0
    texels: int = 0
    samples: np.ndarray | None = None
    weights: np.ndarray | None = None
    shadow_angle: float | None = None
    luminance: float = field(init=False)

    def __post_init__(self):
        self.direction = np.asarray(self.direction, dtype=np.float64).reshape(3)
        self.power = np.asarray(self.power, dtype=np.float64).reshape(3)
        self.angle = float(self.angle)
        self.luminance = float(_luma(self.power))
        self.shadow_angle = None if self.shadow_angle is None else float(self.shadow_angle)
        if (self.samples is None) != (self.weights is None):
            raise ValueError("a light's samples and weights come together")
        if self.samples is not None:
            self.samples = np.asarray(self.samples, dtype=np.float64).reshape(-1, 3)
            self.weights = np.asarray(self.weights, dtype=np.float64).reshape(-1)
            if len(self.samples) != len(self.weights) or not len(self.weights):
                raise ValueError("a light needs one weight per sample, and at least one sample")


def _texel_geometry(height, width):
    """Per row: solid angle, integral of cos^2(e) de and of sin(e) cos(e) de; per column: phi.

    A texel's direction integral is integral d dOmega = (A_j 2 sin(h) cos(phi_k),
    A_j 2 sin(h) sin(phi_k), B_j 2 h) with h = pi / W, A_j = integral cos^2 e de and
    B_j = integral sin e cos e de over the row (dOmega = cos e de dphi).
    """
    _, edges = row_elevations(height)
    half = np.pi / width
    solid = 2.0 * half * np.diff(np.sin(edges))
    cos2 = 0.5 * np.diff(edges) + 0.25 * np.diff(np.sin(2.0 * edges))
    sincos = 0.5 * np.diff(np.sin(edges) ** 2)
    return solid, cos2, sincos, column_azimuths(width), half


def _luma(values):
    """Rec.709 luminance of (..., 3) values, channel by channel (no threaded BLAS gemv)."""
    return values[..., 0] * LUMA[0] + values[..., 1] * LUMA[1] + values[..., 2] * LUMA[2]


def _luminance(rgb):
    """(H, W) float64 luminance after the projection's pixel policy (NaN, Inf -> 0, negatives
    -> 0), LUMINANCE_ROWS rows at a time so that no full float64 copy of the image is made."""
    height, width, _ = rgb.shape
    lum = np.empty((height, width))
    for start in range(0, height, LUMINANCE_ROWS):
        values = rgb[start : start + LUMINANCE_ROWS].astype(np.float64)
        np.fmax(values, 0.0, out=values)  # fmax maps NaN to 0
        part = lum[start : start + LUMINANCE_ROWS]
        np.multiply(values[..., 0], LUMA[0], out=part)
        part += values[..., 1] * LUMA[1]
        part += values[..., 2] * LUMA[2]
    infinite = np.isinf(lum)  # only a +Inf channel makes it infinite: repair those texels
    if infinite.any():
        lum[infinite] = _luma(_repair(rgb[infinite]))
    return lum


def _repair(values):
    """float64 copy with NaN and +-Inf set to 0 and negatives clamped to 0 (projection policy)."""
    values = np.fmax(np.asarray(values, dtype=np.float64), 0.0)
    values[np.isinf(values)] = 0.0
    return values


def _world_power(lum, solid):  # sum of lum * texel solid angle
    return float(lum.sum(axis=1) @ solid)


def _threshold(lum, solid, world_power, mean_factor=MEAN_FACTOR, compact_fraction=COMPACT_FRACTION):
    threshold = mean_factor * world_power / (4.0 * np.pi)
    rows, cols = np.nonzero(lum > threshold)
    texel_solid = solid[rows]
    budget = compact_fraction * 4.0 * np.pi
    if texel_solid.sum() <= budget:
        return threshold
    values = lum[rows, cols]
    order = np.argsort(-values, kind="stable")
    covered = np.cumsum(texel_solid[order])
    # The first texel that would overflow the budget sets T: everything strictly brighter fits.
    first = min(int(np.searchsorted(covered, budget, side="right")), len(order) - 1)
    return max(threshold, float(values[order[first]]))


def auto_threshold(
    pixels: npt.ArrayLike, *, mean_factor: float = MEAN_FACTOR, compact_fraction: float = COMPACT_FRACTION
) -> float:
    """Luminance threshold T above which texels are split off as lights.

    T = max(3 * mean, T_compact): mean is the solid-angle-weighted mean luminance of the image
    (pixel policy of the projection applied), T_compact the smallest value such that the texels
    brighter than it cover at most 10 % of the sphere (a cap of 37 degrees radius). A texel is a
    light only if it is 3 times brighter than the average sky; what is split off that way may be
    a broad patch of sky, shaded by samples of its own texels and drawn by the viewport from
    several shadow maps (docs/lights.md, "Threshold rule"). A uniform or one-colour image gives
    T = 3 * its luminance, so no texel exceeds it.
    mean_factor and compact_fraction replace the 3 and the 10 % (to measure the rule;
    extract_lights always uses the constants).
    """
    rgb = as_rgb_image(pixels)
    lum, solid = _luminance(rgb), _texel_geometry(*rgb.shape[:2])[0]
    return _threshold(lum, solid, _world_power(lum, solid), mean_factor, compact_fraction)


def _is_real(value):
    return not isinstance(value, bool) and isinstance(value, (int, float, np.integer, np.floating))


def _check_arguments(threshold, max_lights, min_share):
    if not _is_real(min_share) or not 0.0 <= min_share <= 1.0:
        raise ValueError(f"min_share must be a number from 0 to 1, got {min_share!r}")
    if (
        isinstance(max_lights, bool)
        or not isinstance(max_lights, (int, np.integer))
        or not 0 <= max_lights <= MAX_LIGHTS
    ):
        raise ValueError(f"max_lights must be an integer 0..{MAX_LIGHTS}, got {max_lights!r}")
    if threshold is not None and not (_is_real(threshold) and 0 <= threshold < np.inf):
        raise ValueError(f"threshold must be finite and >= 0 (or None), got {threshold!r}")
    return (None if threshold is None else float(threshold)), int(max_lights)


def _sphere_neighbour_pairs(flat, height, width):
    """Edges (i, j) between bright texels (sorted flat indices): 8-connectivity in the image,
    joined across the u = 0/1 seam; the texels of the bottom row are all neighbours (they meet at
    the nadir), likewise the top row, linked here as chains in column order."""
    rows, cols = np.divmod(flat, width)
    dense = 16 * len(flat) > height * width
    if dense:  # a lookup table beats the binary search once the bright set is a large share
        position = np.full(height * width, -1, dtype=np.int64)
        position[flat] = np.arange(len(flat))
    sources, targets = [], []
    for d_row, d_col in ((0, 1), (1, -1), (1, 0), (1, 1)):
        inside = np.flatnonzero(rows + d_row < height)
        wanted = (rows[inside] + d_row) * width + (cols[inside] + d_col) % width
        if dense:
            found = position[wanted]
            hit = found >= 0
        else:
            found = np.minimum(np.searchsorted(flat, wanted), len(flat) - 1)
            hit = flat[found] == wanted
        sources.append(inside[hit])
        targets.append(found[hit])
    for lo, hi in ((0, np.searchsorted(flat, width)), (np.searchsorted(flat, (height - 1) * width), len(flat))):
        chain = np.arange(lo, max(lo, hi - 1))
        sources.append(chain)
        targets.append(chain + 1)
    return np.concatenate(sources), np.concatenate(targets)


def _connected_components(count, sources, targets):
    """(count,) region index 0..R-1 of each node, by hooking roots and pointer jumping.

    Invariant parent[x] <= x (so the forest has no cycles). Each round hooks the larger root of
    every edge that still joins two trees onto the smaller one, then jumps pointers until every
    node points at its root; the number of trees with outside edges at least halves per round.
    """
    parent = np.arange(count)
    while sources.size:
        root_s, root_t = parent[sources], parent[targets]
        apart = root_s != root_t
        if not apart.any():
            break
        sources, targets = sources[apart], targets[apart]
        parent[np.maximum(root_s[apart], root_t[apart])] = np.minimum(root_s[apart], root_t[apart])
        while True:
            grand = parent[parent]
            if np.array_equal(grand, parent):
                break
            parent = grand
    roots = np.flatnonzero(parent == np.arange(count))
    index = np.empty(count, dtype=np.int64)
    index[roots] = np.arange(len(roots))
    return index[parent], len(roots)


def extract_lights(
    pixels: npt.ArrayLike,
    threshold: float | None = None,
    max_lights: int = 4,
    *,
    min_share: float = MIN_SHARE,
    samples: int = SAMPLES_PER_LIGHT,
) -> tuple[np.ndarray, list[Light]]:
    """Split the compact bright sources of an equirect image: -> (residual (H, W, 3), [Light]).

    Texels with luminance above T (threshold, or auto_threshold) are scaled to luminance T
    (residual = pixel * T / lum, hue kept); the excess pixel - residual is grouped into regions
    connected on the sphere. The max_lights most powerful regions (by luminance power) become
    lights, strongest first; the excess of the other regions, of any region holding less than
    min_share of the image's luminance power, and of a region with no direction (zero first
    moment) is put back into the residual, so residual + lights is always the input.
    Each light: power = sum excess * texel solid angle (RGB); direction = normalised first
    moment m = sum lum_excess * integral(d dOmega) over its texels (the exact power-weighted mean
    direction of the piecewise-constant excess); angle = radius of the uniform disc with the same
    mean cosine rho = |m| / luminance power, i.e. cos(angle) = 2 rho - 1; samples, weights: up
    to `samples` power-weighted directions over its texels (core.lights.samples.region_samples;
    0: none, the light is shaded as its disc).

    The residual has the input's dtype if float32/float64 (else float64); texels outside the
    lights are copied unchanged (NaN, Inf and negatives are left for the projection to repair).
    """
    threshold, max_lights = _check_arguments(threshold, max_lights, min_share)
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 0:
        raise ValueError(f"samples must be an integer >= 0, got {samples!r}")
    rgb = as_rgb_image(pixels)
    height, width, _ = rgb.shape
    dtype = rgb.dtype if rgb.dtype in (np.float32, np.float64) else np.float64
    residual = np.array(rgb, dtype=dtype)
    if max_lights == 0:
        return residual, []
    solid, cos2, sincos, phi, half = _texel_geometry(height, width)
    lum = _luminance(rgb)
    world_power = _world_power(lum, solid)
    if threshold is None:
        threshold = _threshold(lum, solid, world_power)
    flat = np.flatnonzero(lum > threshold)
    if flat.size == 0:
        return residual, []

    rows, cols = np.divmod(flat, width)
    bright = _repair(rgb[rows, cols])
    kept_values = (bright * (threshold / lum.ravel()[flat])[:, None]).astype(dtype)
    excess = bright - kept_values
    texel_solid = solid[rows]
    # Per texel: RGB power excess * Omega, first moment lum_excess * integral(d dOmega), Omega.
    columns = np.column_stack(
        [
            excess * texel_solid[:, None],
            _luma(excess)[:, None]
            * np.stack(
                [
                    2.0 * np.sin(half) * cos2[rows] * np.cos(phi[cols]),
                    2.0 * np.sin(half) * cos2[rows] * np.sin(phi[cols]),
                    2.0 * half * sincos[rows],
                ],
                axis=1,
            ),
            texel_solid,
        ]
    )
    region, count = _connected_components(len(flat), *_sphere_neighbour_pairs(flat, height, width))
    sums = np.stack([np.bincount(region, weights=c, minlength=count) for c in columns.T], axis=1)
    region_power, region_moment, region_solid = sums[:, :3], sums[:, 3:6], sums[:, 6]
    region_lum = _luma(region_power)
    region_texels = np.bincount(region, minlength=count)
    moment_length = np.sqrt(np.einsum("ij,ij->i", region_moment, region_moment))
    usable = (region_lum > 0.0) & (region_lum >= min_share * world_power) & (moment_length > 1e-12 * region_lum)
    ranked = np.argsort(-region_lum, kind="stable")
    chosen = ranked[usable[ranked]][:max_lights]

    kept_texels = np.isin(region, chosen)
    residual[rows[kept_texels], cols[kept_texels]] = kept_values[kept_texels]

    lights = []
    for r in chosen:
        rho = min(1.0, moment_length[r] / region_lum[r])
        sample_dirs = sample_weights = shadow = None
        direction = region_moment[r] / moment_length[r]
        if samples > 0:
            mine = np.flatnonzero(region == r)
            sample_dirs, sample_weights = region_samples(columns[mine, 3:6], _luma(columns[mine, :3]), samples)
            shadow = median_angle(columns[mine, 3:6], _luma(columns[mine, :3]), direction)
        lights.append(
            Light(
                direction=direction,
                power=region_power[r],
                angle=2.0 * np.arcsin(np.sqrt(1.0 - rho)),
                solid_angle=float(region_solid[r]),
                texels=int(region_texels[r]),
                samples=sample_dirs,
                weights=sample_weights,
                shadow_angle=shadow,
            )
        )
    return residual, lights


def lights_to_array(lights: Iterable[Light]) -> list[float]:
    """Flat list of floats for storage: per light direction (3), power (3), angle (1)."""
    values = [np.concatenate([light.direction, light.power, [light.angle]]) for light in lights]
    return np.concatenate(values).tolist() if values else []


def lights_from_array(values: npt.ArrayLike, samples: npt.ArrayLike | None = None) -> list[Light]:
    """Inverse of lights_to_array. solid_angle is the disc's 2 pi (1 - cos angle); texels 0.
    samples: the lights' samples_to_array (core.lights.samples), or None (lights stored before
    samples existed: every light is its disc)."""
    values = np.asarray(values, dtype=np.float64).ravel()
    if values.size % FLOATS_PER_LIGHT or not np.all(np.isfinite(values)):
        raise ValueError(
            f"stored lights must be finite, {FLOATS_PER_LIGHT} floats per light (got {values.size} values)"
        )
    rows = values.reshape(-1, FLOATS_PER_LIGHT)
    per_light = [None] * len(rows) if samples is None else samples_from_array(samples, len(rows))
    lights = []
    for row, sampled in zip(rows, per_light):
        length = np.linalg.norm(row[:3])
        if length == 0.0 or row[6] < 0.0:
            raise ValueError("a stored light has a zero direction or a negative angle")
        lights.append(
            Light(
                direction=row[:3] / length,
                power=row[3:6],
                angle=row[6],
                solid_angle=2.0 * np.pi * (1.0 - np.cos(row[6])),
                texels=0,
                samples=None if sampled is None else sampled[0],
                weights=None if sampled is None else sampled[1],
                shadow_angle=None if sampled is None else sampled[2],
            )
        )
    return lights


def rotate_lights(lights: Iterable[Light], rotation: npt.ArrayLike) -> list[Light]:
    """Lights with direction R @ direction (R maps the image frame to the world frame, like the
    rotation applied to the world's SH)."""
    rotation = np.asarray(rotation, dtype=np.float64).reshape(3, 3)
    return [
        Light(
            direction=rotation @ light.direction,
            power=light.power.copy(),
            angle=light.angle,
            solid_angle=light.solid_angle,
            texels=light.texels,
            samples=None if light.samples is None else light.samples @ rotation.T,
            weights=None if light.weights is None else light.weights.copy(),
            shadow_angle=light.shadow_angle,
        )
        for light in lights
    ]
