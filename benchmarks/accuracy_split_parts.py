"""Where the split's error comes from (the residual sky's SH band limit against the lights' model),
and what other constants of the threshold rule would give.

Called by benchmarks/accuracy_split.py: parts() for the HDRIs of its sweep, rule() for every HDRI. At each threshold the image is
split as api.project_world splits it (core.lights.extraction.extract_lights at full resolution), and each
part of api.shade is compared with the brute-force quadrature of that part alone: the SH of the
residual against the quadrature of the residual image, and the lights (as their samples, and as
the uniform discs of the moment radius) against the quadrature of their excess texels, every
excess texel a node. All errors are RMS differences of luminance over the vertices divided by
the RMS of the whole image's brute force, so the parts add up (as vectors) to the total error.
"""

import dataclasses

import numpy as np

from prt_addon.core.sh.resample import LUMINANCE as LUMA

THRESHOLDS = [0.0, "old", 5.0, 3.0, 2.0]  # 0: automatic; "old": the rule before samples, OLD_RULE
OLD_RULE = (8.0, 0.01)  # (mean factor, compact fraction)
MAX_LIGHTS = 4
RULES = [(2.0, 0.1), (3.0, 0.1), (4.0, 0.1), (6.0, 0.1), (8.0, 0.1), (3.0, 0.05), (3.0, 0.2), (8.0, 0.01)]


def shade_luminance(objs, scene, lights=None):
    """Luminance of api.shade over the objects, with the scene's lights replaced by `lights`
    (image frame, the Mapping rotation still applied) when given."""
    from prt_addon import api
    from prt_addon.blender.scene import lighting

    if lights is not None:
        lighting.set_lights_override(scene, lights)
    try:
        return np.concatenate([api.shade(o, scene) for o in objs]) @ LUMA
    finally:
        if lights is not None:
            lighting.set_lights_override(scene, None)


def _lights_only(objs, scene, lights):
    """Luminance of the lights' term of api.shade alone (scene.light_shading)."""
    import bpy

    from prt_addon.blender.scene import light_shading, storage

    depsgraph = bpy.context.evaluated_depsgraph_get()
    return (
        np.concatenate(
            [light_shading.light_radiance(o, depsgraph, lights, storage.usable_bake(o.data)[0]) for o in objs]
        )
        @ LUMA
    )


def parts(scene, objs, points, rgb, brute_y, orders, brute_force, quadrature_nodes, coarse):
    """Rows per threshold: {"threshold", "lights", "angles_deg", "sky": {order: err},
    "lights_samples": err, "lights_discs": err}, errors relative to the RMS of brute_y."""
    from prt_addon import api
    from prt_addon.blender.scene import lighting
    from prt_addon.core.lights import extraction as core_lights

    norm = float(np.sqrt(np.mean(brute_y**2)))
    rows = []
    for threshold in THRESHOLDS:
        if threshold == "old":
            t = core_lights.auto_threshold(rgb, mean_factor=OLD_RULE[0], compact_fraction=OLD_RULE[1])
        else:
            t = core_lights.auto_threshold(rgb) if threshold == 0.0 else threshold
        residual, found = core_lights.extract_lights(rgb, t, MAX_LIGHTS)
        excess = rgb - residual
        count = int(np.count_nonzero(excess.max(axis=2) > 0.0))
        sky_truth = brute_force(points, quadrature_nodes(residual, coarse)) @ LUMA
        light_truth = brute_force(points, quadrature_nodes(excess, coarse, bright=max(count, 1))) @ LUMA
        row = {"threshold": threshold, "value": float(t), "lights": len(found), "sky": {}}
        row["angles_deg"] = [float(np.degrees(light.angle)) for light in found]
        for n in orders:
            api.project_world(scene, n, split_lights=True, threshold=t, max_lights=MAX_LIGHTS)
            sky = shade_luminance(objs, scene, lights=[])
            row["sky"][str(n)] = float(np.sqrt(np.mean((sky - sky_truth) ** 2)) / norm)
        world = lighting.world_lights(scene)
        discs = [dataclasses.replace(light, samples=None, weights=None) for light in world]
        for name, model in (("lights_samples", world), ("lights_discs", discs)):
            y = _lights_only(objs, scene, model)
            row[name] = float(np.sqrt(np.mean((y - light_truth) ** 2)) / norm)
        rows.append(row)
    return rows


def rule(scene, objs, rgb, cy, orders):
    """Per (mean factor, compact fraction) of RULES: the threshold auto_threshold would give with
    them, the lights, and api.shade's error against Cycles at each order."""
    from prt_addon import api
    from prt_addon.core.lights import extraction as core_lights

    rows = []
    for mean_factor, compact in RULES:
        t = core_lights.auto_threshold(rgb, mean_factor=mean_factor, compact_fraction=compact)
        row = {"mean_factor": mean_factor, "compact_fraction": compact, "value": float(t)}
        for n in orders:
            api.project_world(scene, n, split_lights=True, threshold=t, max_lights=MAX_LIGHTS)
            y = shade_luminance(objs, scene)
            row[str(n)] = float(np.sqrt(np.mean((y - cy) ** 2)) / np.sqrt(np.mean(cy**2)))
        row["lights"] = int(scene.prt_world.light_count)
        rows.append(row)
    return rows
