"""A wide light's model: power-weighted sample directions drawn from its own region of texels.

A light split off a broad patch of sky (tens of degrees, any shape) is badly represented by one
uniform disc about its mean direction: its cosine term and the shadows it casts both depend on
where its power really is. So each extracted light keeps up to SAMPLES_PER_LIGHT directions s_j
with weights w_j (sum 1): its region's excess texels are split into cells of about equal power
by recursive weighted-median bisection along the cell's principal axis, and each cell becomes one
sample (direction: the cell's normalised first moment, weight: its share of the luminance power).
The shading is then P / pi * sum_j w_j max(0, n . s_j) V(s_j), one ray per sample
(core.lights.visibility); a region of fewer texels has one sample per texel.

Storage (`samples_to_array` / `samples_from_array`): per light its sample count k, its shadow
angle (median_angle; ignored when k is 0), then k rows of (x, y, z, w); a count of 0 is a light
without samples (a disc, as stored before samples existed).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

SAMPLES_PER_LIGHT = 16  # the rays the shading traces per light and point


def region_samples(
    moments: npt.ArrayLike, weights: npt.ArrayLike, count: int = SAMPLES_PER_LIGHT
) -> tuple[np.ndarray, np.ndarray]:
    """(directions (k, 3), weights (k,) summing to 1), k = min(count, texels with weight > 0).

    moments: (N, 3) first moment of each texel's excess (luminance x integral of d dOmega), whose
    direction is the texel's power-weighted centre; weights: (N,) luminance power of each texel.
    The heaviest cell that has more than one texel is split until there are `count` cells: at
    the weighted median of the texel directions projected on the cell's principal axis (largest
    eigenvector of the weighted covariance of the directions), both halves non-empty.
    """
    moments = np.asarray(moments, dtype=np.float64).reshape(-1, 3)
    weights = np.asarray(weights, dtype=np.float64).reshape(-1)
    keep = weights > 0.0
    moments, weights = moments[keep], weights[keep]
    if not len(weights):
        raise ValueError("a light's region has no power")
    length = np.linalg.norm(moments, axis=1)
    dirs = moments / np.where(length > 0.0, length, 1.0)[:, None]
    cells = power_cells(dirs, weights, count)
    cell_weight = [float(weights[cell].sum()) for cell in cells]
    sample_dirs = np.stack([moments[cell].sum(axis=0) for cell in cells])
    sample_dirs /= np.linalg.norm(sample_dirs, axis=1, keepdims=True)
    sample_weights = np.array(cell_weight) / sum(cell_weight)
    return sample_dirs, sample_weights


def power_cells(dirs: np.ndarray, weights: np.ndarray, count: int) -> list[np.ndarray]:
    """Index arrays of at most `count` cells of about equal power over unit directions `dirs`
    (N, 3) with positive `weights` (N,): the heaviest cell of more than one direction is split at
    the weighted median of its directions projected on its principal axis (the largest
    eigenvector of their weighted covariance), both halves non-empty, until there are `count`."""
    cells = [np.arange(len(weights))]
    cell_weight = [float(weights.sum())]
    while len(cells) < count:
        splittable = [i for i, cell in enumerate(cells) if len(cell) > 1]
        if not splittable:
            break
        index = max(splittable, key=lambda i: cell_weight[i])
        cell = cells.pop(index)
        cell_weight.pop(index)
        w, d = weights[cell], dirs[cell]
        centred = d - (w @ d) / w.sum()
        axis = np.linalg.eigh((centred * w[:, None]).T @ centred)[1][:, -1]
        order = np.argsort(centred @ axis, kind="stable")
        cumulative = np.cumsum(w[order])
        split = int(np.searchsorted(cumulative, 0.5 * cumulative[-1])) + 1
        split = min(max(split, 1), len(cell) - 1)
        for part in (cell[order[:split]], cell[order[split:]]):
            cells.append(part)
            cell_weight.append(float(weights[part].sum()))
    return cells


def samples_to_array(lights) -> list[float]:
    """Flat floats: per light its sample count k (0 without samples), its shadow angle (that of
    shadow_angle), then k x (x, y, z, w)."""
    values = []
    for light in lights:
        samples = getattr(light, "samples", None)
        if samples is None:
            values.append(np.array([0.0, light.angle]))
        else:
            rows = np.column_stack([samples, light.weights])
            values.append(np.concatenate([[len(rows), shadow_angle(light)], rows.ravel()]))
    return np.concatenate(values).tolist() if values else []


def samples_from_array(values: npt.ArrayLike, lights: int) -> list[tuple[np.ndarray, np.ndarray, float] | None]:
    """Inverse of samples_to_array for `lights` lights: per light (directions, weights, shadow
    angle) or None.

    Raises ValueError unless the array is finite, holds exactly that many lights, every count is
    a whole number, the shadow angles are >= 0, directions are non-zero and weights are >= 0 with
    a positive sum (they are returned normalised to sum 1, directions to unit length)."""
    values = np.asarray(values, dtype=np.float64).ravel()
    if not np.all(np.isfinite(values)):
        raise ValueError("stored light samples must be finite")
    out: list[tuple[np.ndarray, np.ndarray, float] | None] = []
    at = 0
    for _ in range(lights):
        if at >= values.size or values[at] != int(values[at]) or values[at] < 0:
            raise ValueError("stored light samples: a count is missing or not a whole number")
        count = int(values[at])
        if at + 1 >= values.size or values[at + 1] < 0.0:
            raise ValueError("stored light samples: a shadow angle is missing or negative")
        shadow = float(values[at + 1])
        block = values[at + 2 : at + 2 + 4 * count]
        if block.size != 4 * count:
            raise ValueError("stored light samples are truncated")
        rows = block.reshape(-1, 4)
        at += 2 + 4 * count
        if count == 0:
            out.append(None)
            continue
        length = np.linalg.norm(rows[:, :3], axis=1)
        if np.any(length == 0.0) or np.any(rows[:, 3] < 0.0) or rows[:, 3].sum() <= 0.0:
            raise ValueError("a stored light sample has a zero direction or a negative weight")
        out.append((rows[:, :3] / length[:, None], rows[:, 3] / rows[:, 3].sum(), shadow))
    if at != values.size:
        raise ValueError("stored light samples hold more values than their lights")
    return out


def median_angle(moments: npt.ArrayLike, weights: npt.ArrayLike, direction: npt.ArrayLike) -> float:
    """Radius of one disc standing for the light's penumbra (the viewport's filtered shadow): the
    uniform disc with the same power-median angular distance r from `direction` as the texels,
    1 - cos R = 2 (1 - cos r) (half a cap's solid angle lies within r). A bright core in a faint
    glow (a sun in its halo) gets about the core's radius, where the moment radius is the glow's."""
    moments = np.asarray(moments, dtype=np.float64).reshape(-1, 3)
    weights = np.asarray(weights, dtype=np.float64).reshape(-1)
    length = np.linalg.norm(moments, axis=1)
    cosine = (moments @ np.asarray(direction, dtype=np.float64)) / np.where(length > 0.0, length, 1.0)
    order = np.argsort(-cosine, kind="stable")
    cumulative = np.cumsum(weights[order])
    k = min(int(np.searchsorted(cumulative, 0.5 * cumulative[-1])), len(order) - 1)
    return float(np.arccos(max(-1.0, 1.0 - 2.0 * (1.0 - min(1.0, cosine[order][k])))))


def shadow_angle(light) -> float:
    """The light's penumbra radius for the viewport (median_angle, stored with the samples), never
    more than its moment radius `angle`; a light without one gets its `angle`."""
    value = getattr(light, "shadow_angle", None)
    return float(light.angle) if value is None else float(min(light.angle, value))
