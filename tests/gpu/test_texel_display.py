"""Texel bakes drawn per pixel: render_view's image is the bilinear lookup of shade's texels, through each object's UVs; seams drawn without a line."""

import math

import numpy as np

UNIFORM_TILT = np.zeros((9, 3))
UNIFORM_TILT[0] = np.sqrt(4.0 * np.pi)
UNIFORM_TILT[1] = 0.8  # brighter toward +Y: a gradient over the floor
UNIFORM_TILT[3] = -0.5  # and toward -X


def test_render_view_draws_the_texels_bilinearly(bpy_module, empty_scene, gpu_ready):
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
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.3, -0.2, 0.5))  # a shadow with edges
    lighting.set_light_override(scene, UNIFORM_TILT)
    scene.prt_display.albedo_source = "WHITE"
    api.bake([floor], order=3, samples=256, target="TEXELS", uv_map="UVMap", resolution=16)
    reference = api.shade(floor)
    image = api.render_view(scene, 64, 64)[..., :3]
    # The plane's UVMap is u = x / 4 + 1/2, v = y / 4 + 1/2; the top-down view's row 0 is y = +2.
    ys, xs = np.mgrid[0:64, 0:64]
    uv = np.stack([(xs + 0.5) / 64, 1.0 - (ys + 0.5) / 64], axis=-1).reshape(-1, 2)
    expected = lightmap.bilinear(reference, uv).reshape(64, 64, 3)
    drawn = image.sum(axis=-1) > 0
    assert drawn.mean() > 0.9  # the box is not baked, so not drawn: the floor fills the view
    assert np.abs(image - expected)[drawn].max() < 1e-5
    assert np.ptp(expected[drawn]) > 0.3  # (a real gradient and shadow, not a constant)


def test_the_two_sides_of_a_smooth_seam_agree(bpy_module, empty_scene, monkeypatch):
    """A smooth sphere unwrapped with cuts, lit unevenly: along its seams the two sides' bilinear
    values agree to a fraction of what they differ by without the seam fix."""
    from helpers import texel_scenes as ts

    from prt_addon import api
    from prt_addon.blender.scene import lighting, mesh_read, storage, texel_storage
    from prt_addon.core.transfer import lightmap

    bpy = bpy_module
    bpy.ops.mesh.primitive_uv_sphere_add(segments=16, ring_count=8, radius=1.0)
    ball = bpy.context.object
    bpy.ops.object.shade_smooth()
    ts.lightmap_unwrap(bpy, ball)
    lighting.set_light_override(empty_scene, UNIFORM_TILT)

    def seam_gap():
        api.bake([ball], order=3, samples=64, target="TEXELS", uv_map=ts.LIGHTMAP, resolution=64)
        bake, _ = storage.read_bake_record(ball.data)
        image = texel_storage.read_texel_transfer(bake)
        corners, vertices, _world, normals = mesh_read.world_triangles(ball.data, np.eye(4))
        uvs = mesh_read.read_corner_uvs(ball.data, ts.LIGHTMAP)[corners].astype(np.float64)
        seams = lightmap.seam_pairs(vertices, uvs, normals=normals)
        a, b, _ = seams.samples(64)
        return len(seams), np.abs(lightmap.bilinear(image, a) - lightmap.bilinear(image, b))[:, 0].mean(), image

    count, fixed, image = seam_gap()
    monkeypatch.setattr(lightmap, "fix_seams", lambda img, *_a, **_k: img)
    _count, unfixed, _ = seam_gap()
    assert count > 10
    assert fixed < 0.2 * unfixed, (fixed, unfixed)
    assert fixed < 0.01 * math.sqrt(np.mean(image[..., 0] ** 2))


def test_a_texel_bake_under_a_split_sun_draws_its_shadow_as_shade_traces_it(bpy_module, empty_scene, gpu_ready):
    """With a split light the viewport adds the sun per pixel from its shadow map (as for vertex
    bakes) over the texel sky: on average within 3 % of shade's traced texels (edges differ: the
    map's filter against 4 traced samples a texel)."""
    from prt_addon import api
    from prt_addon.blender.scene import lighting
    from prt_addon.core.lights.extraction import Light
    from prt_addon.core.transfer import lightmap

    bpy = bpy_module
    scene = empty_scene
    bpy.ops.object.camera_add(location=(0.0, 0.0, 10.0))
    camera = bpy.context.object
    camera.data.type = "ORTHO"
    camera.data.ortho_scale = 4.0
    scene.camera = camera
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    floor = bpy.context.object
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.3, -0.2, 0.5))
    sky = np.zeros((9, 3))
    sky[0] = np.sqrt(4.0 * np.pi) * 0.3
    lighting.set_light_override(scene, sky)
    sun = np.array([0.5, 0.3, 0.8]) / np.linalg.norm([0.5, 0.3, 0.8])
    lighting.set_lights_override(scene, [Light(sun, np.array([3.0, 3.0, 3.0]), 0.02)])
    scene.prt_display.albedo_source = "WHITE"
    api.bake([floor], order=3, samples=256, target="TEXELS", uv_map="UVMap", resolution=32)
    reference = api.shade(floor)
    image = api.render_view(scene, 128, 128)[..., :3]
    ys, xs = np.mgrid[0:128, 0:128]
    uv = np.stack([(xs + 0.5) / 128, 1.0 - (ys + 0.5) / 128], axis=-1).reshape(-1, 2)
    expected = lightmap.bilinear(reference, uv).reshape(128, 128, 3)
    drawn = image.sum(axis=-1) > 0
    error = np.abs(image - expected)[drawn].mean()
    assert error < 0.03 * expected[drawn].mean()  # measured 1.5 %
    shadowed = expected[drawn][:, 0] < 0.5 * expected[drawn][:, 0].max()
    assert shadowed.mean() > 0.05  # (the box's shadow is there to be drawn)
    lighting.set_lights_override(scene, None)
