"""A glossy metal floor baked per texel (one quad) with a box on it under city.exr: render_view with the texel bake's specular occlusion against Cycles with direct light only, beside the draw without it (docs/specular.md)."""

import numpy as np
import pytest
from helpers import specular_scenes as ss, texel_glossy_scene as tg

CYCLES_SAMPLES = 128  # two seeds, averaged; 160 x 96 pixels


@pytest.fixture(scope="module")
def glossy_floor(bpy_module, addon):
    from prt_addon import api
    from prt_addon.blender.display import offscreen

    bpy = bpy_module
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    assert offscreen.ensure_gpu()
    floor, box, _cam = tg.glossy_floor_scene(bpy, scene, 0.2)
    api.project_world(scene, order=8, split_lights=True)
    api.bake([floor], order=8, samples=256, target="TEXELS", uv_map="UVMap", resolution=32)
    api.bake([box], order=8, samples=256, target="TEXELS", uv_map="Lightmap", resolution=16)
    seen = ss.object_masks(bpy, scene, {"floor": floor})["floor"]
    # The floor before the box's foot (its mirror direction runs into the box), and all of it.
    near = tg.floor_region_mask(bpy, scene, (tg.BOX_FRONT - 0.5, tg.BOX_FRONT), 0.4) & seen
    return scene, floor, {"before the box": near, "floor": seen}


@pytest.mark.parametrize("roughness", [0.2, 0.45])
def test_the_box_hides_the_sky_from_the_glossy_texel_floor_as_in_cycles(bpy_module, glossy_floor, roughness, capsys):
    """Where the box hides the sky's reflection, the occluded draw is far closer to Cycles than
    the draw without occlusion (relative RMSE of luminance at most half of it; measured 1.57 against
    6.16 at roughness 0.2, 0.29 against 1.42 at 0.45: Cycles is nearly black there, so the errors
    are large fractions of a small mean), its mean at most half as far from Cycles' (0.18 and 0.69
    against 0.10 at 0.2, 0.24 and 0.68 against 0.29 at 0.45), and closer over the whole floor
    (0.215 against 0.577, 0.134 against 0.212)."""
    from prt_addon.blender.display import offscreen

    scene, floor, masks = glossy_floor
    bsdf = next(n for n in floor.active_material.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    bsdf.inputs["Roughness"].default_value = roughness
    occluded = offscreen.render_view(scene)[..., :3].astype(np.float64)
    with tg.without_texel_occlusion():
        unoccluded = offscreen.render_view(scene)[..., :3].astype(np.float64)
    first = ss.cycles_render(bpy_module, scene, CYCLES_SAMPLES, seed=0)
    second = ss.cycles_render(bpy_module, scene, CYCLES_SAMPLES, seed=1)
    reference = 0.5 * (first + second)
    rows = {}
    for name, mask in masks.items():
        assert mask.sum() > 300, name
        rows[name] = {
            "occluded": ss.relative_rmse(occluded, reference, mask),
            "unoccluded": ss.relative_rmse(unoccluded, reference, mask),
            "noise": ss.relative_rmse(first, second, mask) / 2.0,
            "means": tuple(float((image[mask] @ ss.LUMINANCE).mean()) for image in (occluded, unoccluded, reference)),
        }
    with capsys.disabled():
        for name, r in rows.items():
            print(
                f"\nroughness {roughness}, {name}: occluded {r['occluded']:.3f}, without occlusion "
                f"{r['unoccluded']:.3f}, Cycles noise {r['noise']:.3f}; mean luminance "
                "%.3f / %.3f / Cycles %.3f" % r["means"]
            )
    near = rows["before the box"]
    assert near["occluded"] < 0.5 * near["unoccluded"], rows
    new, old, ref = near["means"]
    assert abs(new - ref) < 0.5 * abs(old - ref), rows
    assert rows["floor"]["occluded"] < 0.9 * rows["floor"]["unoccluded"], rows
