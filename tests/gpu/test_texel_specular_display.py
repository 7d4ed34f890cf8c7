"""A texel bake's specular occlusion in render_view: 1 on an open plane (the white furnace), and the sky's reflection hidden beside a box."""

import math

import numpy as np
import pytest
from helpers.display_scenes import add_camera
from helpers.specular_scenes import principled_material
from helpers.worlds import new_world


@pytest.fixture
def white_plane(bpy_module, empty_scene, gpu_ready):
    """A 4 m plane (its UVMap) under a uniform white world at order 8, a camera 1 m high 3 m before it."""
    from prt_addon.blender.world import projection

    bpy = bpy_module
    scene = empty_scene
    scene.prt_display.specular = True
    new_world(bpy, scene, (1.0, 1.0, 1.0), 1.0)
    add_camera(bpy, scene, location=(0.0, -3.0, 1.0), euler=(math.radians(72.0), 0.0, 0.0), size=96)
    scene.view_settings.view_transform = "Standard"
    projection.project_and_store(scene, 8)
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    return scene, bpy.context.object


def _metal(bpy, obj, roughness):
    obj.data.materials.clear()
    obj.data.materials.append(principled_material(bpy, "metal", (1.0, 1.0, 1.0), roughness, 1.0))


def test_an_open_texel_plane_keeps_occlusion_one(bpy_module, white_plane):
    """A white metal plane baked per texel under a white world: every pixel is its occlusion times
    the lobe's white-furnace 1, and nothing hides it: 1 within the bake's quadrature error (256
    directions: measured 0.68 % below 1 at most at roughness 0.2, 0.056 % at 0.8; the draw without
    occlusion is 1 within 1e-7), from grazing to steep views."""
    from prt_addon import api

    scene, plane = white_plane
    api.bake([plane], order=8, samples=256, target="TEXELS", uv_map="UVMap", resolution=16)
    for roughness, bound in ((0.2, 0.01), (0.8, 1e-3)):
        _metal(bpy_module, plane, roughness)
        image = api.render_view(scene)
        pixels = image[..., :3][image[..., 3] > 0.99]
        assert len(pixels) > 3000
        assert np.abs(pixels - 1.0).max() < bound, (roughness, pixels.min(), pixels.max())


def test_a_box_hides_the_sky_from_a_texel_floor(bpy_module, white_plane):
    """The same plane with a box standing on it (in the bake, not drawn): the floor before the
    box's foot, whose mirror direction runs into the box, reflects none of the white sky, the floor
    at the sides (beside the box's reflection) still almost all of it."""
    from prt_addon import api

    bpy = bpy_module
    scene, plane = white_plane
    bpy.ops.mesh.primitive_cube_add(size=0.8, location=(0.0, 0.3, 0.4))
    api.bake([plane], order=8, samples=256, target="TEXELS", uv_map="UVMap", resolution=32)
    _metal(bpy, plane, 0.2)
    image = api.render_view(scene)
    lum, drawn = image[..., 1], image[..., 3] > 0.99
    w = lum.shape[1]
    middle = lum[:, w // 2 - w // 12 : w // 2 + w // 12][drawn[:, w // 2 - w // 12 : w // 2 + w // 12]]
    sides = np.concatenate([lum[:, : w // 8][drawn[:, : w // 8]], lum[:, -w // 8 :][drawn[:, -w // 8 :]]])
    assert len(middle) > 300 and len(sides) > 300
    assert middle.min() < 0.1  # measured 0: the box fills the mirror lobe
    assert sides.mean() > 0.97 and sides.min() > 0.9, (sides.mean(), sides.min())  # measured 0.99, 0.94


def test_a_texel_floor_with_a_roughness_map_draws_each_quadrant_as_its_constants(bpy_module, white_plane):
    """The floor with the box, its Roughness and Metallic from a four-quadrant image (roughness 0.2
    and 0.8): each quadrant's pixels (less 3 at its edges) are the floor drawn with that quadrant's
    constants, occlusion included (its two lobes' sums per pixel, mixed by the pixel's roughness),
    within 1 % of the quadrant's mean; without the box's occlusion the glossy quadrants differ."""
    from helpers import spec_map_scenes as maps

    from prt_addon import api

    bpy = bpy_module
    scene, plane = white_plane
    bpy.ops.mesh.primitive_cube_add(size=0.8, location=(0.4, 0.3, 0.4))
    api.bake([plane], order=8, samples=256, target="TEXELS", uv_map="UVMap", resolution=32)
    plane.data.materials.append(maps.id_material(bpy, maps.quadrant_image(bpy, "ids", maps.ID_COLOURS, "sRGB")))
    scene.prt_display.specular = False
    masks = maps.quadrant_masks(api.render_view(scene))
    scene.prt_display.specular = True
    plane.data.materials.clear()
    plane.data.materials.append(maps.orm_material(bpy, maps.orm_image(bpy))[0])
    drawn = api.render_view(scene)[..., :3]
    for q, (roughness, metallic) in maps.QUADRANTS.items():
        mask = masks[q]
        assert mask.sum() > 100, {k: int(m.sum()) for k, m in masks.items()}
        plane.data.materials.clear()
        plane.data.materials.append(maps.principled(bpy, f"c{q}", roughness=roughness, metallic=metallic)[0])
        expected = api.render_view(scene)[..., :3]
        error = np.abs(drawn[mask] - expected[mask]).max() / expected[mask].mean()
        assert error < 0.01, (q, error)


def _numpy_occlusion(scene, plane, roughness, size):
    """(H, W) the full transfer's occlusion of the floor plane (z = 0, its UVMap u = x / 4 + 1/2)
    at each pixel's reflection direction, from its stored texels looked up bilinearly at the pixel's
    UV (core: lightmap.bilinear, occlusion.transfer_occlusion), NaN off the plane; row 0 the top."""
    from prt_addon.blender.display import offscreen
    from prt_addon.blender.scene import storage, texel_storage
    from prt_addon.core.sh import analytic, basis
    from prt_addon.core.specular import brdf, occlusion
    from prt_addon.core.transfer import lightmap

    info, _problem = storage.usable_bake(plane.data, check_topology=False)
    texels = texel_storage.from_tiles(
        texel_storage.read_pixels(info.image), info.resolution, texel_storage.total_groups(info)
    )
    view, proj = offscreen.camera_matrices(scene, size, size)
    inverse = np.linalg.inv(proj @ view)
    j, i = np.mgrid[0:size, 0:size]
    ndc = np.stack([(i + 0.5) / size * 2 - 1, 1 - (j + 0.5) / size * 2], -1).reshape(-1, 2)
    ends = [np.c_[ndc, np.full(len(ndc), z), np.ones(len(ndc))] @ inverse.T for z in (-1.0, 1.0)]
    near, far = (e[:, :3] / e[:, 3:] for e in ends)
    point = near + (far - near) * (near[:, 2] / (near[:, 2] - far[:, 2]))[:, None]
    uv = point[:, :2] / 4.0 + 0.5
    v = np.asarray(scene.camera.matrix_world.translation) - point
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    r = 2.0 * v[:, 2:] * np.array([0.0, 0.0, 1.0]) - v
    t = lightmap.bilinear(texels[..., :64], uv)
    alpha = float(brdf.alpha_of(roughness))
    occ = occlusion.transfer_occlusion(
        t,
        analytic.clamped_cosine_coeffs(8, np.array([0.0, 0.0, 1.0])),
        basis.sh_basis(r, 8),
        occlusion.lobe_bands(alpha, 8),
    )
    inside = np.all((uv > 0) & (uv < 1), axis=1) & (near[:, 2] > far[:, 2])
    return np.where(inside, occ, np.nan).reshape(size, size)


@pytest.mark.parametrize("bounces", [0, 1])
def test_the_texel_occlusion_is_the_full_transfer_at_each_pixel(bpy_module, white_plane, bounces):
    """The floor with the box, a white metal (no diffuse: each pixel is its occlusion), baked
    direct only and with a bounce (the image then holds the direct tiles and the bounced ones in
    another tile grid): every pixel of the floor is the core's full-transfer occlusion of the
    stored texels at the pixel's UV and reflection direction, within 1e-4 (measured 2.1e-6 with
    and without the bounce), and the box's occlusion shows."""
    from prt_addon import api

    bpy = bpy_module
    scene, plane = white_plane
    bpy.ops.mesh.primitive_cube_add(size=0.8, location=(0.0, 0.3, 0.4))
    _metal(bpy, plane, 0.3)
    api.bake([plane], order=8, samples=256, target="TEXELS", uv_map="UVMap", resolution=16, bounces=bounces)
    image = api.render_view(scene)
    expected = _numpy_occlusion(scene, plane, 0.3, image.shape[0])
    drawn = (image[..., 3] > 0.99) & np.isfinite(expected)
    assert drawn.sum() > 3000 and expected[drawn].min() < 0.1
    assert np.abs(image[..., 1] - expected)[drawn].max() < 1e-4


def test_a_texel_floor_with_an_ior_map_draws_each_half_as_its_constant(bpy_module, white_plane):
    """The floor with the box, a glossy dielectric whose IOR comes from an image (1.2 on u < 0.5,
    2.0 on the other half): the IOR map's sampler and the texel tiles' are bound together, and each
    half of the floor (less 3 pixels at the join) is the floor drawn with that half's constant IOR
    within 1 % of its mean, the two halves' draws measurably apart."""
    from helpers import spec_map_scenes as maps

    from prt_addon import api

    bpy = bpy_module
    scene, plane = white_plane
    bpy.ops.mesh.primitive_cube_add(size=0.8, location=(0.0, 0.3, 0.4))
    api.bake([plane], order=8, samples=256, target="TEXELS", uv_map="UVMap", resolution=32)
    plane.data.materials.append(maps.socket_material(bpy, "iors", maps.halves_image(bpy, "iors", 1.2, 2.0), "IOR")[0])
    drawn = api.render_view(scene)
    covered = drawn[..., 3] > 0.99
    columns = np.arange(drawn.shape[1])[None, :]
    halves = {1.2: covered & (columns < drawn.shape[1] // 2 - 3), 2.0: covered & (columns >= drawn.shape[1] // 2 + 3)}
    expected = {}
    for ior, mask in halves.items():
        assert mask.sum() > 1000
        plane.data.materials.clear()
        material, bsdf = maps.principled(bpy, f"ior{ior}", roughness=0.2, metallic=0.0)
        bsdf.inputs["IOR"].default_value = ior
        plane.data.materials.append(material)
        expected[ior] = api.render_view(scene)[..., :3]
        error = np.abs(drawn[..., :3][mask] - expected[ior][mask]).max() / expected[ior][mask].mean()
        assert error < 0.01, (ior, error)
    apart = np.abs(expected[1.2] - expected[2.0])[halves[2.0]].mean() / expected[2.0][halves[2.0]].mean()
    assert apart > 0.015, apart  # (measured 0.028: the white sky, mostly diffuse light)
