"""Principled spheres (roughness x metallic) on a ground under city.exr: render_view against Cycles with
direct light only (0 bounces) from the same camera, per object, beside the diffuse-only draw and
EEVEE on the same scene (docs/specular.md; benchmarks/accuracy_specular.py prints the table)."""

import numpy as np
import pytest
from helpers import specular_scenes as ss

CYCLES_SAMPLES = 128  # two seeds, averaged; 160 x 96 pixels: about 6 s each on 2 cores
NOISY = 0.5  # where the reference's own noise is above this, the comparison measures nothing
# (the glossy metal's mirror image of the sun: a few pixels of 1e4, 225 % noise at 128 samples)


@pytest.fixture(scope="module")
def renders(bpy_module, addon):
    from prt_addon import api
    from prt_addon.blender.display import offscreen

    bpy = bpy_module
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    assert offscreen.ensure_gpu()
    spheres, ground, _cam = ss.spheres_scene(bpy, scene)
    api.project_world(scene, order=8, split_lights=True)
    api.bake([*spheres.values(), ground], order=8, samples=512)
    masks = ss.object_masks(bpy, scene, {**spheres, "ground": ground})
    scene.prt_display.specular = False
    diffuse = offscreen.render_view(scene)[..., :3].astype(np.float64)
    scene.prt_display.specular = True
    prt = offscreen.render_view(scene)[..., :3].astype(np.float64)
    first = ss.cycles_render(bpy, scene, CYCLES_SAMPLES, seed=0)
    second = ss.cycles_render(bpy, scene, CYCLES_SAMPLES, seed=1)
    eevee = ss.eevee_render(bpy, scene, 16)
    return masks, prt, diffuse, first, second, eevee


def test_specular_spheres_against_cycles(renders):
    """PRT within 1.25 times EEVEE's error on each object, and better than the diffuse-only draw."""
    masks, prt, diffuse, first, second, eevee = renders
    reference = 0.5 * (first + second)
    rows = []
    for name, mask in masks.items():
        assert mask.sum() > 300, name
        error = ss.relative_rmse(prt, reference, mask)
        before = ss.relative_rmse(diffuse, reference, mask)
        noise = ss.relative_rmse(first, second, mask) / 2.0  # the mean's: sqrt(2) x sqrt(2)
        ee = ss.relative_rmse(eevee, reference, mask)
        rows.append(f"{name}: {error:.3f} (diffuse only {before:.3f}, EEVEE {ee:.3f}, Cycles noise {noise:.3f})")
        if noise >= NOISY:  # the median pixel, which the sun's few noisy pixels do not move
            y, y_before, y_ref = (img[mask] @ ss.LUMINANCE for img in (prt, diffuse, reference))
            assert np.median(np.abs(y - y_ref)) < 0.5 * np.median(np.abs(y_before - y_ref)), rows[-1]
            continue
        assert error <= 1.25 * ee, rows[-1]
        if name.endswith("_m1"):  # metals: the diffuse-only draw was chalk
            assert error < 0.5 * before, rows[-1]
        else:
            assert error <= before + 0.005, rows[-1]
    print("\n".join(rows))
