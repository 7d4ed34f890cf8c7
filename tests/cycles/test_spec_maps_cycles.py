"""A sphere whose Roughness and Metallic come from a metallic-roughness image: render_view against Cycles (direct light only), each quadrant beside the same comparison for the quadrant's constant material."""

import numpy as np
from helpers import spec_map_scenes as maps, specular_scenes as ss
from helpers.display_scenes import add_camera
from helpers.worlds import bundled_hdri_path, new_world, use_image

SAMPLES = 128  # 128 x 128 pixels, about 3 s a render on 2 cores


def _use(obj, material):
    obj.data.materials.clear()
    obj.data.materials.append(material)


def test_mapped_sphere_against_cycles(bpy_module, addon, capsys):
    """Over each quadrant's pixels (less 3 at the edges), the mapped draw's relative RMSE of
    luminance against Cycles' render of the mapped material is within 1.25 times (plus Cycles' own
    noise) the constant draw's against Cycles' render of the quadrant's constant material."""
    from prt_addon import api
    from prt_addon.blender.display import offscreen

    bpy = bpy_module
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    assert offscreen.ensure_gpu()
    use_image(new_world(bpy, scene), bpy.data.images.load(bundled_hdri_path("forest"), check_existing=True))
    add_camera(bpy, scene, location=(0.0, -4.5, 0.0), size=128)
    scene.view_settings.view_transform = "Standard"
    bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, radius=1.0)
    obj = bpy.context.active_object
    obj.data.shade_smooth()
    obj.rotation_euler = (0.0, 0.0, np.radians(90.0))
    bpy.context.view_layer.update()
    api.project_world(scene, order=8, split_lights=True)
    api.bake([obj], order=8, samples=256)
    scene.prt_display.specular = False
    _use(obj, maps.id_material(bpy, maps.quadrant_image(bpy, "ids", maps.ID_COLOURS, "sRGB")))
    masks = maps.quadrant_masks(offscreen.render_view(scene))
    scene.prt_display.specular = True
    mapped, _tex = maps.orm_material(bpy, maps.orm_image(bpy))
    _use(obj, mapped)
    prt = offscreen.render_view(scene)[..., :3].astype(np.float64)
    first = ss.cycles_render(bpy, scene, SAMPLES, seed=0)
    second = ss.cycles_render(bpy, scene, SAMPLES, seed=1)
    reference = 0.5 * (first + second)
    rows = {}
    for q, (roughness, metallic) in maps.QUADRANTS.items():
        mask = masks[q]
        assert mask.sum() > 200
        noise = 0.5 * ss.relative_rmse(first, second, mask)  # (of the two seeds' mean)
        _use(obj, maps.principled(bpy, f"c{q}", roughness=roughness, metallic=metallic)[0])
        constant = offscreen.render_view(scene)[..., :3].astype(np.float64)
        constant_reference = ss.cycles_render(bpy, scene, 2 * SAMPLES, seed=2)
        rows[q] = (ss.relative_rmse(prt, reference, mask), ss.relative_rmse(constant, constant_reference, mask), noise)
        _use(obj, mapped)
    with capsys.disabled():
        for q, (m, c, n) in rows.items():
            print(
                f"\nroughness {maps.QUADRANTS[q][0]}, metallic {maps.QUADRANTS[q][1]}: mapped {100 * m:.1f} %, "
                f"constant {100 * c:.1f} %, Cycles noise {100 * n:.1f} %"
            )
    for q, (m, c, n) in rows.items():
        assert m < 1.25 * c + 2 * n, (q, rows)
