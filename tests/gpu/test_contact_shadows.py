"""Sun shadows at joins in the display: a wall under a roof and a wall beside a side wall, shadowed to the join, against the closed form.

The walls carry an unshadowed clamped-cosine transfer, so the constant sky SH lights them to
exactly SKY and a sun adds P/pi (n . s) where its shadow map sees it. Before the shadow lookups
moved along the contact tangent, the one or two pixel rows next to the join came out lit
(0.47 against 0.20) under every sun direction (docs/display.md, "Joins").
"""

import math

import numpy as np
import pytest
from helpers.display_scenes import add_camera, add_env_world, clamped_cosine_rows, set_light, write_bake
from helpers.shadow_scenes import POWER, SKY, set_suns, sky_light

SIZE = 512


def _quad(bpy, scene, name, corners, cuts=1):
    """A quad (cuts x cuts faces) through four corners, baked with the clamped cosine about its normal."""
    corners = np.asarray(corners, dtype=np.float64)
    u, v = np.meshgrid(np.linspace(0.0, 1.0, cuts + 1), np.linspace(0.0, 1.0, cuts + 1), indexing="ij")
    u, v = u.ravel()[:, None], v.ravel()[:, None]
    points = (1 - u) * (1 - v) * corners[0] + u * (1 - v) * corners[1] + u * v * corners[2] + (1 - u) * v * corners[3]
    index = np.arange((cuts + 1) ** 2).reshape(cuts + 1, cuts + 1)
    faces = [
        (int(index[i, j]), int(index[i + 1, j]), int(index[i + 1, j + 1]), int(index[i, j + 1]))
        for i in range(cuts)
        for j in range(cuts)
    ]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(p) for p in points], [], faces)
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    normal = np.cross(corners[1] - corners[0], corners[3] - corners[0])
    write_bake(obj, clamped_cosine_rows(np.tile(normal / np.linalg.norm(normal), (len(points), 1)), 3), 3)
    return obj


@pytest.fixture
def join_scene(bpy_module, empty_scene, gpu_ready):
    scene = empty_scene
    add_env_world(bpy_module, scene)
    add_camera(bpy_module, scene, location=(0.0, -6.0, 1.0), euler=(math.pi / 2, 0.0, 0.0), size=SIZE)
    set_light(scene, sky_light())
    scene.prt_display.albedo_source = "WHITE"
    return scene


def _pixels(scene, points):
    from prt_addon.blender.display import offscreen

    view, proj = offscreen.camera_matrices(scene, SIZE, SIZE)
    clip = np.c_[points, np.ones(len(points))] @ (proj @ view).T
    ndc = clip[:, :2] / clip[:, 3:4]
    return np.floor((1.0 - ndc[:, 1]) * 0.5 * SIZE).astype(int), np.floor((ndc[:, 0] + 1.0) * 0.5 * SIZE).astype(int)


def _render_with_sun(bpy, scene, direction):
    import prt_addon.api as api
    from prt_addon.core.lights.extraction import Light

    d = np.asarray(direction, dtype=np.float64)
    set_suns(scene, [Light(direction=d / np.linalg.norm(d), power=POWER, angle=0.01)])
    bpy.context.view_layer.update()
    return api.render_view(scene, SIZE, SIZE)


@pytest.mark.parametrize("cuts", [1, 6])
@pytest.mark.parametrize("forward", [0.1, 0.3, 0.5, 2.0])
def test_wall_under_roof_is_shadowed_to_the_join(bpy_module, join_scene, cuts, forward):
    """A roof over the front of a wall (z = 2, y in [-1, 0]), the sun above and in front: the roof
    shadows the whole wall (the sun's ray from (x, 0, z) reaches z = 2 at y = -forward (2 - z),
    inside the roof for z > 2 - 1 / forward). Every pixel up to the join is the sky alone."""
    scene = join_scene
    _quad(bpy_module, scene, "wall", [(-1, 0, 0), (1, 0, 0), (1, 0, 2), (-1, 0, 2)], cuts)
    _quad(bpy_module, scene, "roof", [(-1.5, -1, 2), (1.5, -1, 2), (1.5, 0, 2), (-1.5, 0, 2)], cuts)
    image = _render_with_sun(bpy_module, scene, (0.0, -forward, 1.0))
    z = np.linspace(max(0.05, 2.0 - 1.0 / forward + 0.05), 2.0, 400)
    x = np.linspace(-0.9, 0.9, 400)
    rows, cols = _pixels(scene, np.c_[x, np.full_like(z, -1e-4), z])
    got = image[rows, cols, :3]
    np.testing.assert_allclose(got, np.tile(SKY, (len(z), 1)), rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("sun", [(1.0, -0.5, 0.2), (1.0, -0.1, 0.3), (1.0, -0.05, 0.1)])
def test_wall_beside_side_wall_is_shadowed_to_the_join(bpy_module, join_scene, sun):
    """A side wall (x = 1, y in [-1, 0]) meets the back wall at their vertical join; the sun from
    the right and front, over the side wall, leaves the back wall in its shadow for x > 1 - h
    where the shadow reaches: the pixels along the join are the sky alone; far left, lit."""
    scene = join_scene
    _quad(bpy_module, scene, "back", [(-1, 0, 0), (1, 0, 0), (1, 0, 2), (-1, 0, 2)])
    _quad(bpy_module, scene, "side", [(1, -1, 0), (1, 0, 0), (1, 0, 2), (1, -1, 2)])
    s = np.array(sun)
    image = _render_with_sun(bpy_module, scene, s)
    s /= np.linalg.norm(s)
    z = np.linspace(0.1, 1.9, 300)
    # The sun's ray from (x, 0, z) reaches x = 1 at y = s_y / s_x (1 - x) >= -1 and z + s_z / s_x
    # (1 - x) < 2 for these x and z: inside the side wall.
    x = np.linspace(0.8, 0.99, 300)  # (the pixels at x = 1 show the side wall edge-on)
    rows, cols = _pixels(scene, np.c_[x, np.full_like(x, -1e-4), z])
    np.testing.assert_allclose(image[rows, cols, :3], np.tile(SKY, (len(x), 1)), rtol=1e-5, atol=1e-6)
    # Without the side wall the same pixels are lit: the shadow above is the side wall's.
    bpy_module.data.objects.remove(bpy_module.data.objects["side"])
    image = _render_with_sun(bpy_module, scene, s)
    lit = SKY + POWER / np.pi * max(0.0, -s[1])
    np.testing.assert_allclose(image[rows, cols, :3], np.tile(lit, (len(x), 1)), rtol=1e-4, atol=1e-5)


def test_room_corners_in_the_display_like_shade(bpy_module, empty_scene, gpu_ready):
    """The single-quad room of the Cycles test (tests/cycles/test_contact_lights_cycles.py, where
    api.shade's corners are checked against Cycles) baked and drawn under courtyard.exr with its
    lights split: 3 cm inside each corner the display agrees with api.shade at the corner. Before
    the shadow lookups moved along the contact tangent, the floor's back-right corner was drawn
    at 0.110 against 0.021."""
    from helpers import contact_lights as cl

    import prt_addon.api as api
    from prt_addon.blender.display import offscreen

    bpy, scene = bpy_module, empty_scene
    cl.hdri_world(bpy, scene)
    size = 1024
    add_camera(bpy, scene, location=(0.0, -10.0, 2.0), euler=(math.pi / 2, 0.0, 0.0), size=size)
    objects = [cl.mesh_object(bpy, scene, name, cl.quad(corners)) for name, corners in cl.room_quads().items()]
    cl.white(bpy, objects)
    scene.prt_display.albedo_source = "WHITE"
    bpy.context.view_layer.update()
    api.bake(objects, order=cl.ORDER, samples=cl.DIRECTIONS)
    api.project_world(scene, cl.ORDER, split_lights=True)
    image = api.render_view(scene, size, size)
    view, proj = offscreen.camera_matrices(scene, size, size)
    for obj in objects:
        shade = cl.shade_corners(api, obj, scene) @ cl.LUMA
        position, normal = cl.corner_frame(obj)
        towards = position.mean(axis=0) - position
        inside = position + 0.03 * towards / np.linalg.norm(towards, axis=1, keepdims=True) + 1e-3 * normal
        clip = np.c_[inside, np.ones(len(inside))] @ (proj @ view).T
        ndc = clip[:, :2] / clip[:, 3:4]
        rows = np.floor((1.0 - ndc[:, 1]) * 0.5 * size).astype(int)
        cols = np.floor((ndc[:, 0] + 1.0) * 0.5 * size).astype(int)
        drawn = image[rows, cols, :3] @ cl.LUMA
        print(obj.name, " ".join(f"{a:.3f}/{b:.3f}" for a, b in zip(drawn, shade)))
        assert np.all(image[rows, cols, 3] == 1.0)
        assert np.all(np.abs(drawn - shade) <= 0.03 + 0.1 * shade), obj.name
