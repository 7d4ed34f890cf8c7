"""Sun lights in the display: per-pixel n.s with shadow maps, against closed forms and traced rays.

A baked ground grid (unshadowed transfer, so a constant sky SH lights it to exactly the sky
radiance) under an unbaked box that only casts; lights injected with lighting.set_lights_override.
"""

import math

import numpy as np
import pytest
from helpers.display_scenes import bake_sphere
from helpers.shadow_scenes import POWER, SIZE, SKY, ground_pixels, render, set_suns


def sun(direction, angle=0.01, power=POWER):
    from prt_addon.core.lights.extraction import Light

    d = np.asarray(direction, dtype=np.float64)
    return Light(direction=d / np.linalg.norm(d), power=power, angle=angle)


def grid_points(half, step=0.05):
    xs = np.arange(-half, half + 1e-9, step)
    x, y = np.meshgrid(xs, xs)
    return np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]


def test_no_lights_is_todays_image(bpy_module, ground_scene):
    """An empty light list and no override draw the plain PRT path; lights of zero power go
    through the sun shader and add exactly 0 to the same interpolated SH radiance."""
    scene, _ground = ground_scene
    sphere = bake_sphere(bpy_module, 3, segments=24, rings=12)
    sphere.location = (1.5, 1.5, 1.5)
    plain = render(scene)
    set_suns(scene, [])
    np.testing.assert_array_equal(render(scene), plain)
    set_suns(scene, [sun((0.3, 0.2, 1.0), power=(0.0, 0.0, 0.0))])
    np.testing.assert_array_equal(render(scene), plain)
    set_suns(scene, None)
    np.testing.assert_array_equal(render(scene), plain)


def test_box_shadow_straight_down(bpy_module, ground_scene):
    """Light along +Z: under the box only the sky; far outside sky + P/pi (n.s = 1, V = 1)."""
    scene, _ground = ground_scene
    set_suns(scene, [sun((0.0, 0.0, 1.0))])
    image = render(scene)
    points = grid_points(3.8)
    rows, cols = ground_pixels(scene, points)
    got = image[rows, cols, :3]
    assert np.all(image[rows, cols, 3] == 1.0)
    inside = np.max(np.abs(points[:, :2]), axis=1) < 0.4
    outside = np.max(np.abs(points[:, :2]), axis=1) > 0.7
    assert inside.sum() > 100
    assert outside.sum() > 1000
    # V is exactly 0 or 1 there, so only float32 rounding separates the image from the closed form.
    np.testing.assert_allclose(got[inside], np.tile(SKY, (inside.sum(), 1)), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(got[outside], np.tile(SKY + POWER / np.pi, (outside.sum(), 1)), rtol=1e-5, atol=1e-6)


def test_mapping_rotation_moves_the_shadow(bpy_module, ground_scene):
    """The real path: a Mapping node on the world turns the injected light by 60 degrees; the
    shadow follows to where the rotated direction projects the box, and n.s drops to cos 60."""
    from prt_addon.blender.scene import lighting
    from prt_addon.blender.world import nodes as world_nodes

    scene, _ground = ground_scene
    set_suns(scene, [sun((0.0, 0.0, 1.0))])
    before = render(scene)
    node = world_nodes.ensure_mapping_node(scene.world)
    node.inputs["Rotation"].default_value = (math.radians(60.0), 0.0, 0.0)
    s = lighting.world_lights(scene)[0].direction
    assert s[2] == pytest.approx(0.5, abs=1e-6)
    after = render(scene)
    centre = np.array([0.0, 0.0, 1.0])
    shadow_centre = centre - s * (centre[2] / s[2])
    assert np.linalg.norm(shadow_centre[:2]) == pytest.approx(math.sqrt(3.0), rel=1e-4)
    (r0, r1), (c0, c1) = ground_pixels(scene, np.array([[0.0, 0.0, 0.0], shadow_centre]))
    np.testing.assert_allclose(before[r0, c0, :3], SKY, rtol=1e-5)  # under the box before
    np.testing.assert_allclose(after[r0, c0, :3], SKY + POWER / np.pi * 0.5, rtol=1e-4)
    np.testing.assert_allclose(after[r1, c1, :3], SKY, rtol=1e-5)  # the shadow moved there
    np.testing.assert_allclose(before[r1, c1, :3], SKY + POWER / np.pi, rtol=1e-5)


def test_vertices_agree_with_traced_visibility(bpy_module, ground_scene):
    """At the ground's vertices away from shadow edges the image equals the exact per-vertex
    sky + P/pi * max(0, n.s) * V, V traced with Embree on the scene's triangles (disc rays)."""
    from prt_addon.blender.display import shadows
    from prt_addon.core.lights import visibility
    from prt_addon.core.trace.raytrace import EmbreeOccluder

    scene, ground = ground_scene
    sphere = bake_sphere(bpy_module, 3, segments=32, rings=16, radius=0.6)
    sphere.location = (-1.5, 1.2, 1.2)
    bpy_module.context.view_layer.update()
    light = sun((0.35, -0.25, 1.0), angle=0.02)
    set_suns(scene, [light])
    image = render(scene)
    depsgraph = bpy_module.context.evaluated_depsgraph_get()
    objects = shadows.caster_objects(scene)
    positions, triangles = shadows.caster_triangles(objects, depsgraph)
    occluder = EmbreeOccluder(positions, triangles)
    mw = np.array(ground.matrix_world)
    local = np.array([v.co for v in ground.data.vertices])
    points = local @ mw[:3, :3].T + mw[:3, 3]
    normals = np.tile([0.0, 0.0, 1.0], (len(points), 1))
    vis = visibility.light_visibility(points, normals, [light], occluder, rays_per_light=16)[:, 0]
    # Away from edges: the same V within 4 texels (2048 map over the 8.6 m box: 4.2 mm a texel),
    # a pixel (the image is read at the pixel holding the vertex: 34 mm) and the penumbra, in
    # every direction, so neither the map's sampling nor the filter can differ from the traced V.
    texel = shadows.update_shadow_maps(scene, [light], depsgraph).maps[0].texel
    pixel = 2.0 * 12.0 * math.tan(0.5 * scene.camera.data.angle) / SIZE
    margin = 4.0 * texel + 1.5 * pixel + 2.0 * math.tan(light.angle) * 2.0
    same = np.ones(len(points), dtype=bool)
    for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (-1, -1), (1, -1), (-1, 1)):
        moved = points + margin * np.array([dx, dy, 0.0])
        same &= visibility.light_visibility(moved, normals, [light], occluder, rays_per_light=16)[:, 0] == vis
    to_camera = np.array(scene.camera.location) - points
    to_camera /= np.linalg.norm(to_camera, axis=1, keepdims=True)
    seen = ~np.asarray(
        occluder.occluded((points + 1e-4 * normals).astype(np.float32), to_camera.astype(np.float32)), dtype=bool
    )
    # The unbaked box is not drawn: the ground under it is seen; the baked sphere hides some.
    seen |= np.max(np.abs(points[:, :2]), axis=1) < 0.5
    interior = (np.max(np.abs(points[:, :2]), axis=1) < 3.9) & seen
    keep = same & interior & ((vis == 0.0) | (vis == 1.0))
    assert (keep & (vis == 0.0)).sum() > 30
    assert (keep & (vis == 1.0)).sum() > 1000
    want = SKY + visibility.light_irradiance(normals[keep], [light], vis[keep, None])
    rows, cols = ground_pixels(scene, points[keep])
    got = image[rows, cols, :3]
    np.testing.assert_allclose(got, want, rtol=1e-4, atol=1e-5)
    # api.shade adds the split lights with its own traced V, shadowed as the bake was (by every
    # visible mesh for a shadowed bake): it agrees at the same vertices.
    import prt_addon.api as api

    ground.data["prt_bake"]["shadows"] = True
    np.testing.assert_allclose(got, api.shade(ground, scene)[keep], rtol=1e-4, atol=1e-5)
    # And the vertices at the edges are not all lit or all dark: the shadow is really there.
    assert ((vis > 0.0) & (vis < 1.0)).sum() + (~same).sum() > 10


def test_viewport_callback_with_suns_matches_render_view(bpy_module, ground_scene, monkeypatch):
    """The draw handler draws the shadow maps inside the viewport's frame (another framebuffer
    bound, then the viewport's restored): the same image as render_view(display=True), drawn
    twice (cached), and render_view's linear image under the Standard view transform."""
    import types

    import gpu
    import mathutils

    import prt_addon.api as api
    from prt_addon.blender.display import colour, draw as display_draw, offscreen, shadows

    scene, _ground = ground_scene
    set_suns(scene, [sun((0.3, -0.2, 1.0)), sun((-0.5, 0.1, 1.0), angle=0.05, power=(1.0, 1.0, 1.0))])
    scene.view_settings.exposure = 0.0
    linear = render(scene)
    reference = api.render_view(scene, SIZE, SIZE, display=True)
    shadows.clear_shadows()
    view, proj = offscreen.camera_matrices(scene, SIZE, SIZE)
    context = types.SimpleNamespace(
        scene=scene,
        region_data=types.SimpleNamespace(perspective_matrix=mathutils.Matrix((proj @ view).tolist())),
        view_layer=bpy_module.context.view_layer,
        space_data=None,
        evaluated_depsgraph_get=bpy_module.context.evaluated_depsgraph_get,
    )
    off = gpu.types.GPUOffScreen(SIZE, SIZE, format="RGBA32F")
    frames = []
    with off.bind():
        fb = gpu.state.active_framebuffer_get()
        for _ in range(2):
            fb.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
            display_draw.draw_viewport(context)
            frames.append(np.asarray(fb.read_color(0, 0, SIZE, SIZE, 4, 0, "FLOAT")).T.reshape(SIZE, SIZE, 4)[::-1])
    off.free()
    mask = reference[..., 3] > 0
    assert mask.sum() > 10000
    for frame in frames:
        np.testing.assert_allclose(colour.encode_display(frame[mask, :3]), reference[mask, :3], rtol=1e-5, atol=1e-6)
    scene.view_settings.view_transform, scene.view_settings.gamma = "Standard", 1.0
    standard = api.render_view(scene, SIZE, SIZE, display=True)
    x = np.clip(linear[mask, :3], 0.0, 1.0)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
    np.testing.assert_allclose(standard[mask, :3], srgb, atol=1.5 / 255)
    dark = linear[mask, 0] < SKY[0] + 0.5 * POWER[0] / np.pi
    assert 100 < dark.sum() < mask.sum() - 1000  # the shadows are in the picture


def test_sampled_light_cosine_is_the_sum_over_its_samples(bpy_module, ground_scene):
    """A light with samples, some below the ground's horizon: far from the box the ground shows
    sky + P/pi sum_j w_j max(0, s_j . z), as core.lights.extraction.light_irradiance and api.shade give."""
    from prt_addon.core.lights.extraction import Light
    from prt_addon.core.lights.visibility import light_irradiance

    scene, ground = ground_scene
    samples = np.array([[0.9, 0.0, 0.3], [0.95, 0.1, -0.2], [0.8, -0.3, 0.5], [1.0, 0.0, 0.05]])
    samples /= np.linalg.norm(samples, axis=1, keepdims=True)
    weights = np.array([0.4, 0.3, 0.2, 0.1])
    mean = weights @ samples
    light = Light(mean / np.linalg.norm(mean), POWER, 0.3, samples=samples, weights=weights)
    set_suns(scene, [light])
    image = render(scene)
    cosine = weights @ np.maximum(samples[:, 2], 0.0)
    want = SKY + POWER / np.pi * cosine
    np.testing.assert_allclose(light_irradiance([[0.0, 0.0, 1.0]], [light])[0], POWER / np.pi * cosine, rtol=1e-12)
    points = grid_points(3.8)
    points = points[points[:, 0] > 1.0]  # the light is towards +X: the box's shadow falls to -X
    rows, cols = ground_pixels(scene, points)
    np.testing.assert_allclose(image[rows, cols, :3], np.tile(want, (len(points), 1)), rtol=1e-5, atol=1e-6)
    import prt_addon.api as api

    ground.data["prt_bake"]["shadows"] = True
    far = np.array([v.co[0] > 1.0 for v in ground.data.vertices])
    np.testing.assert_allclose(api.shade(ground, scene)[far], np.tile(want, (far.sum(), 1)), rtol=1e-5, atol=1e-6)


def test_the_shadow_filter_uses_the_shadow_angle(bpy_module, ground_scene):
    """A light with samples all along its direction and a shadow angle of 0.01 draws the image of
    a plain disc light of angle 0.01, although its moment radius is 0.3 (a sun in a halo)."""
    from prt_addon.core.lights.extraction import Light

    scene, _ground = ground_scene
    d = np.array([0.35, -0.25, 1.0]) / np.linalg.norm([0.35, -0.25, 1.0])
    set_suns(scene, [sun(d, angle=0.01)])
    disc = render(scene)
    halo = Light(d, POWER, 0.3, samples=np.tile(d, (4, 1)), weights=np.full(4, 0.25), shadow_angle=0.01)
    set_suns(scene, [halo])
    np.testing.assert_allclose(render(scene), disc, rtol=1e-6, atol=1e-7)
    set_suns(scene, [Light(d, POWER, 0.3, samples=np.tile(d, (4, 1)), weights=np.full(4, 0.25))])
    assert np.abs(render(scene) - disc).max() > 0.05  # the 0.3 radius softens the box's shadow
