"""Interreflected texel bakes drawn per pixel: render_view's image is the bilinear lookup of shade's texels, the bounced tiles included (grey and coloured)."""

import numpy as np
import pytest

UNIFORM_TILT = np.zeros((9, 3))
UNIFORM_TILT[0] = np.sqrt(4.0 * np.pi)
UNIFORM_TILT[1] = 0.8  # brighter toward +Y
UNIFORM_TILT[3] = -0.5  # and toward -X


@pytest.mark.parametrize("colour", [None, (0.9, 0.2, 0.1, 1.0)], ids=["grey", "red box"])
def test_render_view_draws_the_bounced_texels_as_shade_gives_them(bpy_module, empty_scene, gpu_ready, colour):
    from prt_addon import api
    from prt_addon.blender.scene import lighting
    from prt_addon.core.transfer import lightmap

    bpy = bpy_module
    scene = empty_scene
    bpy.ops.object.camera_add(location=(0.0, 0.0, 10.0), rotation=(0.0, 0.0, 0.0))
    camera = bpy.context.object
    camera.data.type = "ORTHO"
    camera.data.ortho_scale = 4.0
    scene.camera = camera
    scene.render.resolution_x = scene.render.resolution_y = 64
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    floor = bpy.context.object
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.3, -0.2, 0.5))  # light bounces off it
    if colour is not None:
        material = bpy.data.materials.new("Red")
        material.use_nodes = True
        material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = colour
        bpy.context.object.data.materials.append(material)
    lighting.set_light_override(scene, UNIFORM_TILT)
    scene.prt_display.albedo_source = "WHITE"
    kwargs = {"order": 3, "samples": 256, "target": "TEXELS", "uv_map": "UVMap", "resolution": 16}
    api.bake([floor], **kwargs)
    direct = api.shade(floor)
    report = api.bake([floor], bounces=2, **kwargs)
    assert report.bounce_channels == (1 if colour is None else 3)
    reference = api.shade(floor)
    image = api.render_view(scene, 64, 64)[..., :3]
    ys, xs = np.mgrid[0:64, 0:64]
    uv = np.stack([(xs + 0.5) / 64, 1.0 - (ys + 0.5) / 64], axis=-1).reshape(-1, 2)
    expected = lightmap.bilinear(reference, uv).reshape(64, 64, 3)
    drawn = image.sum(axis=-1) > 0
    assert drawn.mean() > 0.9
    assert np.abs(image - expected)[drawn].max() < 1e-5
    # The bounce is there to be drawn: the floor beside the box is brighter than direct light alone.
    gained = (reference - direct).max(axis=(0, 1))
    assert gained.max() > 0.02
    if colour is not None:
        assert gained[0] > 2.0 * gained[2]  # (the red box tints what it bounces)
