"""The split lights as SH coefficients: what an interreflected bake bounces of their light.

A light of RGB power P (the integral of its radiance) spread evenly over a cap of angular radius
a about s has the coefficients of core.sh.analytic.cap_coeffs with radiance P / (2 pi (1 - cos a));
a point light (a = 0) has P y_i(s). The direct light of the lights is shaded analytically with
sharp shadows; their bounced light goes through the bounced transfer, whose band limit smooths
the lit pattern it gathers (docs/bake.md, "Interreflection").
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from ..sh.analytic import cap_coeffs
from ..sh.basis import sh_basis


def lights_sh(lights: Iterable, order: int) -> np.ndarray:
    """(order**2, 3) float64 coefficients of the lights (objects with direction, power, angle)."""
    total = np.zeros((order * order, 3))
    for light in lights:
        power = np.asarray(light.power, dtype=np.float64).reshape(3)
        direction = np.asarray(light.direction, dtype=np.float64).reshape(3)
        angle = float(light.angle)
        if angle > 1e-6:
            solid = 2.0 * np.pi * (1.0 - np.cos(angle))
            total += cap_coeffs(order, direction, angle, power / solid)
        else:
            total += sh_basis(direction[None], order)[0][:, None] * power[None, :]
    return total
