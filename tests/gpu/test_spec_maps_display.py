"""Roughness and Metallic from a metallic-roughness image, drawn per pixel by render_view: each quadrant as the constant material of its values."""

import numpy as np
import pytest
from helpers import spec_map_scenes as maps
from helpers.display_scenes import add_camera
from helpers.worlds import bundled_hdri_path, new_world, use_image


@pytest.fixture
def sphere(bpy_module, empty_scene, gpu_ready):
    from prt_addon.blender.world import projection

    bpy = bpy_module
    scene = empty_scene
    scene.prt_display.specular = True
    use_image(new_world(bpy, scene), bpy.data.images.load(bundled_hdri_path("forest"), check_existing=True))
    add_camera(bpy, scene, size=128)
    scene.view_settings.view_transform = "Standard"
    projection.project_and_store(scene, 8)
    obj = maps.uv_sphere(bpy, 8)
    obj.rotation_euler = (0.0, 0.0, np.radians(90.0))  # u = 0.5 (the halves' edge) faces the camera
    bpy.context.view_layer.update()
    return scene, obj


def _use(obj, material):
    obj.data.materials.clear()
    obj.data.materials.append(material)


def test_the_map_draws_each_quadrant_as_its_constants(bpy_module, sphere):
    """A sphere whose Roughness (G) and Metallic (B) come from a four-quadrant image, glossy and
    rough, dielectric and metal: every pixel of a quadrant (less 3 at its edges) is the pixel of
    the sphere drawn with that quadrant's constants, within 1 % of its mean (0.05 % on average); the constant draw of
    the node's own (unused) 0.5 / 0.5 is far off."""
    import prt_addon.api as api

    bpy = bpy_module
    scene, obj = sphere
    ids = maps.quadrant_image(bpy, "ids", maps.ID_COLOURS, "sRGB")
    _use(obj, maps.id_material(bpy, ids))
    scene.prt_display.specular = False
    masks = maps.quadrant_masks(api.render_view(scene))
    scene.prt_display.specular = True
    material, _tex = maps.orm_material(bpy, maps.orm_image(bpy))
    _use(obj, material)
    drawn = api.render_view(scene)[..., :3]
    unused_constants = drawn.copy()
    for q, (roughness, metallic) in maps.QUADRANTS.items():
        mask = masks[q]
        assert mask.sum() > 200, {k: int(m.sum()) for k, m in masks.items()}
        constant, _bsdf = maps.principled(bpy, f"c{q}", roughness=roughness, metallic=metallic)
        _use(obj, constant)
        expected = api.render_view(scene)[..., :3]
        error = np.abs(drawn[mask] - expected[mask]).max() / expected[mask].mean()
        mean_error = np.abs(drawn[mask] - expected[mask]).mean() / expected[mask].mean()
        # (measured: at most 0.5 %, 0.013 % on average, on the glossy metal: the map's 0.2 is
        # 0.19995 in the half-float texture, and its sharp reflection shows it)
        assert error < 0.01 and mean_error < 0.0005, (q, error, mean_error)
        _use(obj, maps.principled(bpy, "half", roughness=0.5, metallic=0.5)[0])
        unused_constants = api.render_view(scene)[..., :3]
        off = np.abs(unused_constants[mask] - expected[mask]).mean() / expected[mask].mean()
        assert off > 0.05, (q, off)
        _use(obj, material)
