"""Shading by the split lights: rays over a light's disc or samples, their visibility, E/pi.

A light is a disc of angular radius `angle` about `direction` (core.lights.extraction.Light); a point sees
power / pi * C * V of it. Without samples, C = max(0, n . s) and V is the fraction of rays over
the disc that are not occluded. With samples s_j, weights w_j (core.lights.samples), C = sum_j w_j
max(0, n . s_j) and V = sum_j w_j max(0, n . s_j) V_j / C, one ray per sample: the product is
the power-weighted sum over the light's own texels, sum_j w_j max(0, n . s_j) V_j.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ..serial_blas import matmul_serial

if TYPE_CHECKING:
    from .extraction import Light

CHUNK_RAYS = 1 << 16  # rays per occluder call in light_visibility (a few MB)


def disc_directions(direction: npt.ArrayLike, angle: float, count: int) -> np.ndarray:
    """(count, 3) unit directions over the cap of half-angle `angle` about `direction`.

    Stratified in solid angle: `count` equal-area rings, the innermost one's sample at the centre
    when count is odd, then pairs of opposite points at the mid-area polar angle of each pair of
    rings, turning by the golden angle. The mean is along `direction`; count = 1 is the centre.
    """
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
        raise ValueError(f"count must be an integer >= 1, got {count!r}")
    centre = np.asarray(direction, dtype=np.float64).reshape(3)
    centre = centre / np.linalg.norm(centre)
    # Orthonormal tangents (Duff et al. 2017, "Building an orthonormal basis, revisited").
    x, y, z = centre
    sign = 1.0 if z >= 0.0 else -1.0
    a, b = -1.0 / (sign + z), -x * y / (sign + z)
    tangent = np.array([1.0 + sign * x * x * a, sign * b, -sign * x])
    bitangent = np.array([b, sign + y * y * a, -y])
    odd = count % 2
    pairs = np.arange(count // 2)
    # Ring k covers the area fractions [(odd + 2k) / count, (odd + 2k + 2) / count] of the cap.
    fraction = (odd + 2.0 * pairs + 1.0) / count
    one_minus_cos = fraction * (1.0 - np.cos(angle))
    sin_theta = np.sqrt(np.maximum(0.0, one_minus_cos * (2.0 - one_minus_cos)))
    cos_theta = 1.0 - one_minus_cos
    turn = pairs * np.pi * (3.0 - np.sqrt(5.0))
    offsets = [np.cos(turn)[:, None] * tangent + np.sin(turn)[:, None] * bitangent]
    offsets.append(-offsets[0])
    points = [cos_theta[:, None] * centre + sin_theta[:, None] * o for o in offsets]
    if odd:
        points.insert(0, centre[None, :])
    return np.concatenate(points)


def _unit_rows(vectors: npt.ArrayLike) -> np.ndarray:
    v = np.asarray(vectors, dtype=np.float64).reshape(-1, 3)
    length = np.sqrt(np.einsum("ij,ij->i", v, v))
    ok = np.isfinite(length) & (length > 1e-12)
    return np.divide(v, length[:, None], out=np.zeros_like(v), where=ok[:, None])


def light_cosines(normals: npt.ArrayLike, lights: Sequence[Light]) -> np.ndarray:
    """(P, L) cosine term C of each light: max(0, n . s), or sum_j w_j max(0, n . s_j) over its
    samples. Zero normals give 0."""
    normals = _unit_rows(normals)
    out = np.zeros((len(normals), len(lights)))
    for index, light in enumerate(lights):
        if light.samples is None:
            out[:, index] = np.maximum(0.0, matmul_serial(normals, light.direction))
        else:
            out[:, index] = np.maximum(0.0, matmul_serial(normals, light.samples.T)) @ light.weights
    return out


def light_irradiance(
    normals: npt.ArrayLike, lights: Sequence[Light], visibility: npt.ArrayLike | None = None
) -> np.ndarray:
    """(P, 3) radiance shown under the lights: sum_l power_l / pi * C[:, l] * V[:, l].

    That is E / pi, the unit of the SH shading sum_i L_i t_i (transfer max(0, n . w) / pi * V).
    C is light_cosines; visibility: (P, L) fractions in [0, 1] (light_visibility), or None for 1.
    """
    normals = _unit_rows(normals)
    if not lights:
        return np.zeros((len(normals), 3))
    powers = np.stack([light.power for light in lights])
    weight = light_cosines(normals, lights) / np.pi
    if visibility is not None:
        visibility = np.asarray(visibility, dtype=np.float64)
        if visibility.shape != weight.shape:
            raise ValueError(f"visibility must have shape {weight.shape}, got {visibility.shape}")
        weight = weight * visibility
    return matmul_serial(weight, powers)


def light_visibility(
    points: npt.ArrayLike,
    normals: npt.ArrayLike,
    lights: Sequence[Light],
    occluder: Any,
    rays_per_light: int = 16,
    offset: npt.ArrayLike | None = None,
    tangents: npt.ArrayLike | None = None,
) -> np.ndarray:
    """(P, L) fraction of each light seen from each point: of its disc, by rays_per_light rays
    to disc_directions; of a light with samples, by one ray per sample, the fraction of its
    cosine term C (light_cosines) whose rays are free.

    occluder follows the core.trace.raytrace protocol: occluded(origins f32 (N, 3), dirs f32 (N, 3))
    -> bool (N,). Ray origins are point + offset * unit normal, offset scalar or (P,) as in the
    transfer bake; None: the bake's rule max(1e-4 * bounding-box diagonal, 1e-5 * largest
    |coordinate|) over the points. tangents: None or (P, 3), each point's
    core.transfer.contact.inward_tangents: the origins move by offset along them too, into the
    point's own surface, as the bake's do (docs/bake.md, "Contacts"). Disc rays at or below the
    tangent plane count as blocked (the surface hides them) and are not traced; points with the
    light's centre below the horizon get 0 (their irradiance is 0 anyway). A disc light of
    angle 0 gets one ray.
    """
    if isinstance(rays_per_light, bool) or not isinstance(rays_per_light, (int, np.integer)) or rays_per_light < 1:
        raise ValueError(f"rays_per_light must be an integer >= 1, got {rays_per_light!r}")
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    normals = _unit_rows(normals)
    if len(points) != len(normals):
        raise ValueError("points and normals must have the same length")
    if offset is None:
        extent = np.ptp(points, axis=0) if len(points) else np.zeros(3)
        biggest = float(np.abs(points).max()) if len(points) else 0.0
        offset = max(1e-4 * float(np.linalg.norm(extent)), 1e-5 * biggest, 1e-30)
    offset = np.broadcast_to(np.asarray(offset, dtype=np.float64), (len(points),))
    lift = normals
    if tangents is not None:
        tangents = np.asarray(tangents, dtype=np.float64).reshape(-1, 3)
        if len(tangents) != len(points):
            raise ValueError("tangents must give one row per point")
        lift = normals + tangents
    origins = points + offset[:, None] * lift
    visibility = np.zeros((len(points), len(lights)))
    for index, light in enumerate(lights):
        if light.samples is None:
            rays = disc_directions(light.direction, light.angle, 1 if light.angle == 0 else int(rays_per_light))
            facing = np.flatnonzero(matmul_serial(normals, light.direction) > 0.0)
        else:
            rays = light.samples
            facing = np.flatnonzero((matmul_serial(normals, rays.T) > 0.0).any(axis=1))
        step = max(1, CHUNK_RAYS // len(rays))
        for start in range(0, len(facing), step):
            chosen = facing[start : start + step]
            cosine = matmul_serial(normals[chosen], rays.T)  # (n, k)
            which, ray = np.nonzero(cosine > 0.0)
            free = np.zeros(cosine.shape)
            if which.size:
                blocked = np.asarray(
                    occluder.occluded(origins[chosen][which].astype(np.float32), rays[ray].astype(np.float32)),
                    dtype=bool,
                )
                free[which, ray] = ~blocked
            if light.samples is None:
                visibility[chosen, index] = free.mean(axis=1)
            else:
                weight = np.maximum(cosine, 0.0) * light.weights
                visibility[chosen, index] = (weight * free).sum(axis=1) / weight.sum(axis=1)
    return visibility
