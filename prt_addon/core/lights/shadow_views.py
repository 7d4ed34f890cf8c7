"""The viewport's shadow views of the split lights: one map along a compact light, one per sample group of a wide one.

The viewport draws each light's shadow from orthographic depth maps filtered by PCSS, whose
penumbra is that of a uniform disc about the map's direction. That holds for a sun or a softbox;
a light split off tens of degrees of sky casts the average of the shadows of all its directions,
which no single filtered map gives (the penumbra of a 40 degree disc is wider than the filter
can reach, and its blocker depths differ across the disc). So a light whose shadow angle
(core.lights.samples.shadow_angle) exceeds WIDE_ANGLE gets one view per group of its samples:
each view's map is drawn along the group's mean direction and filtered over the group's own
share of the light, sqrt(m / k) times its shadow angle for m of its k samples, and it shades
with the cosine term of its own samples only. With one sample per group this is api.shade's
sum_j w_j max(0, n . s_j) V(s_j) with V read from the map of s_j instead of traced.

Each wide light gets min(k, max_wide_views // wide lights) groups (power_cells of its samples);
every other light has one view holding all its samples. Every map is drawn again whenever the
lights turn, each a raster of all the casters, so the wide maps together may draw at most
WIDE_TRIANGLES triangles (wide_view_budget): a heavier scene gets fewer groups per wide light,
down to one, which is the compact lights' single filtered map.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .samples import power_cells, shadow_angle

WIDE_ANGLE = np.radians(5.0)  # shadow angles above this are drawn from several maps
MAX_WIDE_VIEWS = 48  # maps of the wide lights together (the viewport's layered texture): 3 wide lights x 16
MAX_SAMPLES = 16  # samples per light the viewport shades (core.lights.samples.SAMPLES_PER_LIGHT)
WIDE_TRIANGLES = 4_000_000  # caster triangles drawn into the wide lights' maps per redraw of them


@dataclass
class ShadowView:
    """One shadow map: the light it belongs to, its unit direction, its filter radius (radians),
    the samples it shades (k, 3) with their weights (k,) (a share of the light's power: a
    light's views sum to 1) and whether it is a wide light's view."""

    light: int
    direction: np.ndarray
    angle: float
    samples: np.ndarray
    weights: np.ndarray
    wide: bool


def light_samples(light, max_samples: int = MAX_SAMPLES) -> tuple[np.ndarray, np.ndarray]:
    """(unit directions (k, 3), weights (k,) summing to 1): the first max_samples samples of the
    light, renormalised, or its direction alone when it has none."""
    if light.samples is None:
        d = np.asarray(light.direction, dtype=np.float64)
        return (d / np.linalg.norm(d))[None, :], np.ones(1)
    count = min(len(light.samples), max_samples)
    dirs = np.asarray(light.samples[:count], dtype=np.float64)
    weights = np.asarray(light.weights[:count], dtype=np.float64)
    return dirs / np.linalg.norm(dirs, axis=1, keepdims=True), weights / weights.sum()


def wide_view_budget(triangles: int, max_wide_views: int = MAX_WIDE_VIEWS) -> int:
    """How many wide maps a scene of `triangles` caster triangles draws: WIDE_TRIANGLES // triangles,
    between 1 and max_wide_views."""
    return int(min(max_wide_views, max(1, WIDE_TRIANGLES // max(1, int(triangles)))))


def is_wide(light, wide_angle: float = WIDE_ANGLE) -> bool:
    return light.samples is not None and len(light.samples) > 1 and shadow_angle(light) > wide_angle


def shadow_views(
    lights, wide_angle: float = WIDE_ANGLE, max_wide_views: int = MAX_WIDE_VIEWS, max_samples: int = MAX_SAMPLES
) -> list[ShadowView]:
    """The views of `lights` (core.lights.extraction.Light), light by light in order."""
    wide = [is_wide(light, wide_angle) for light in lights]
    per_wide = max(1, max_wide_views // max(1, sum(wide)))
    views = []
    for index, (light, spread) in enumerate(zip(lights, wide)):
        dirs, weights = light_samples(light, max_samples)
        angle = shadow_angle(light)
        if not spread:
            d = np.asarray(light.direction, dtype=np.float64)
            views.append(ShadowView(index, d / np.linalg.norm(d), angle, dirs, weights, False))
            continue
        cells = power_cells(dirs, weights, min(len(dirs), per_wide))
        for cell in cells:
            mean = weights[cell] @ dirs[cell]
            length = np.linalg.norm(mean)
            direction = mean / length if length > 0.0 else dirs[cell[0]]
            share = angle * np.sqrt(len(cell) / len(dirs))
            views.append(ShadowView(index, direction, share, dirs[cell], weights[cell], True))
    return views
