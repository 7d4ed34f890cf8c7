"""A texel-baked open plane drawn from above and from below: render_view is the bilinear lookup of shade's texels of the side seen."""

import math

import numpy as np
import pytest

SIZE = 64
SKY = np.zeros((9, 3))
SKY[0] = np.sqrt(4.0 * np.pi)
SKY[1] = 0.8  # brighter toward +Y
SKY[2] = -1.2  # and from below: the underside is the brighter side
SKY[3] = -0.5


@pytest.mark.parametrize("sun", [False, True])
@pytest.mark.parametrize("mirrored", [False, True])
def test_each_side_draws_its_own_texels(bpy_module, empty_scene, gpu_ready, sun, mirrored):
    """A box under the plane's middle shadows its underside; a sun from above (split light)
    lights the top only. A mirrored plane turns gl_FrontFacing over and must not swap the sides."""
    from prt_addon import api
    from prt_addon.blender.scene import lighting
    from prt_addon.core.lights.extraction import Light
    from prt_addon.core.transfer import lightmap

    bpy, scene = bpy_module, empty_scene
    bpy.ops.object.camera_add()
    camera = bpy.context.object
    camera.data.type = "ORTHO"
    camera.data.ortho_scale = 4.0
    scene.camera = camera
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    plane = bpy.context.object
    if mirrored:
        plane.scale = (-1.0, 1.0, 1.0)
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.3, -0.2, -0.8))
    lighting.set_light_override(scene, SKY)
    direction = np.array([0.5, 0.3, 0.8]) / np.linalg.norm([0.5, 0.3, 0.8])
    lighting.set_lights_override(scene, [Light(direction, np.array([3.0, 3.0, 3.0]), 0.02)] if sun else None)
    scene.prt_display.albedo_source = "WHITE"
    api.bake([plane], order=3, samples=256, target="TEXELS", uv_map="UVMap", resolution=16)
    ys, xs = np.mgrid[0:SIZE, 0:SIZE]
    u = (xs + 0.5) / SIZE
    u = 1.0 - u if mirrored else u  # (x = -4 (u - 1/2) on the mirrored plane)
    results = {}
    for side, location, rotation, v in (
        ("FRONT", (0.0, 0.0, 10.0), (0.0, 0.0, 0.0), 1.0 - (ys + 0.5) / SIZE),  # row 0 is y = +2
        ("BACK", (0.0, 0.0, -10.0), (math.pi, 0.0, 0.0), (ys + 0.5) / SIZE),  # row 0 is y = -2
    ):
        camera.location, camera.rotation_euler = location, rotation
        bpy.context.view_layer.update()
        image = api.render_view(scene, SIZE, SIZE)[..., :3]
        reference = api.shade(plane, scene, side=side)
        expected = lightmap.bilinear(reference, np.stack([u, v], axis=-1).reshape(-1, 2)).reshape(SIZE, SIZE, 3)
        drawn = image.sum(axis=-1) > 0
        assert drawn.mean() > 0.9
        results[side] = (np.abs(image - expected)[drawn].mean() / expected[drawn].mean(), expected[drawn].mean())
    lighting.set_lights_override(scene, None)
    print(f"\nsun {sun}, mirrored {mirrored}: (mean |drawn - shade| / mean, mean) {results}")
    # The drawn texels are shade's bilinear lookup (measured 2e-8 to 2e-7 relative; the sun's
    # shadow map has nothing to shadow on the top, and the sun does not reach the underside: with
    # the suns' normal not flipped on back faces it would be drawn there).
    assert results["FRONT"][0] < 1e-5 and results["BACK"][0] < 1e-5
    # The sides differ: the sky's bright lower half (and the box's shadow) below, the sun above.
    assert results["BACK"][1] > 1.2 * results["FRONT"][1] if not sun else results["FRONT"][1] > results["BACK"][1]
