"""Specular occlusion estimates against the brute-force lobe integral, on three kinds of visibility: holes, a wall beside the point, a slab over it.

    .venv/bin/python benchmarks/accuracy_occlusion.py

For a floor point (normal +z) that sees (1) a cone of half-angle 0.3 to 1.5 rad about its normal
(a hole: the case of docs/specular.md's first table), (2) everything but an infinite wall at
distance 0.3 to 1 of height 0.5 or 1 (a box's foot), (3) only the directions more than 0.5 or 1
rad from the normal (under a slab: a table), and the GGX lobe tilted 0 to 1.3 rad toward, across
and away from the occluder: the mean absolute error of no occlusion (1), the cones
(core.specular.occlusion.specular_occlusion) and the full transfer of order 4, 6 and 8
(transfer_occlusion) against sum(D max(r.l, 0) max(n.l, 0) V) / sum(D max(r.l, 0) max(n.l, 0)) over
200,000 Fibonacci directions (the transfer the exact projection of V max(n.l, 0) / pi, no bake noise).
"""

import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from prt_addon.core.sh import analytic, basis
from prt_addon.core.sh.directions import fibonacci_directions
from prt_addon.core.specular import brdf, occlusion

ROUGHNESS = (0.1, 0.2, 0.3, 0.45, 0.6, 0.8, 1.0)
ORDER = 8


def visibilities(d):
    """{kind: [(N,) bool visibility]} of the three kinds."""
    out = {"hole": [d[:, 2] > np.cos(theta) for theta in (0.3, 0.6, 0.9, 1.2, 1.5)], "wall": [], "slab": []}
    for distance, height in ((0.3, 1.0), (0.5, 1.0), (1.0, 1.0), (1.0, 0.5)):
        with np.errstate(divide="ignore", invalid="ignore"):
            out["wall"].append(~((d[:, 0] > 0) & (distance / d[:, 0] * d[:, 2] < height)))
    out["slab"] = [d[:, 2] < np.cos(theta) for theta in (0.5, 1.0)]
    return out


def main():
    d = fibonacci_directions(200_000)
    normal = np.array([0.0, 0.0, 1.0])
    y = basis.sh_basis(d, ORDER)
    t_open = analytic.clamped_cosine_coeffs(ORDER, normal)
    errors = {}
    for kind, cases in visibilities(d).items():
        for visible in cases:
            t = y.T @ (visible * np.maximum(d[:, 2], 0.0) / np.pi) * (4.0 * np.pi / len(d))
            for tilt in np.linspace(0.0, 1.3, 6):
                for azimuth in (0.0, np.pi / 2, np.pi):
                    r = np.array([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)])
                    y_r = basis.sh_basis(r[None], ORDER)[0]
                    for roughness in ROUGHNESS:
                        alpha = float(brdf.alpha_of(roughness))
                        lobe = brdf.ggx_d(np.sqrt((1.0 + d @ r) / 2.0), alpha) * np.maximum(d @ r, 0.0)
                        lobe *= np.maximum(d[:, 2], 0.0)
                        truth = (lobe * visible).sum() / lobe.sum()
                        estimates = {"none": 1.0, "cones": float(occlusion.specular_occlusion(t[:4], normal, r, alpha))}
                        for n in (4, 6, 8):
                            bands = occlusion.lobe_bands(alpha, n)
                            full = occlusion.transfer_occlusion(t[: n * n], t_open[: n * n], y_r[: n * n], bands)
                            estimates[f"full {n}"] = float(full)
                        for name, value in estimates.items():
                            errors.setdefault((kind, name, roughness), []).append(abs(value - truth))
    names = ("none", "cones", "full 4", "full 6", "full 8")
    print("mean absolute error of the occlusion; roughness " + " ".join(f"{r:>5}" for r in ROUGHNESS))
    for kind in ("hole", "wall", "slab", "all"):
        print(kind)
        for name in names:
            row = []
            for roughness in ROUGHNESS:
                kinds = ("hole", "wall", "slab") if kind == "all" else (kind,)
                row.append(np.mean(sum((errors[(k, name, roughness)] for k in kinds), [])))
            print(f"  {name:8s}" + " ".join(f"{e:5.3f}" for e in row))


if __name__ == "__main__":
    main()
