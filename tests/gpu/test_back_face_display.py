"""Back faces in the viewport: render_view of a single-sided roof from above and from below against api.shade of each side."""

import math

import numpy as np
import pytest
from helpers.worlds import image_world, sunny_image

from prt_addon import api
from prt_addon.core.trace import raytrace

pytestmark = pytest.mark.skipif(not raytrace.EMBREE_AVAILABLE, reason="embreex not available")

SIZE = 128


def _scene(bpy, scene, mirrored):
    image_world(bpy, scene, sunny_image(128, 256, sun=(0.4, 0.8), power=400.0))
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=12, y_subdivisions=12, size=6.0)
    floor = bpy.context.active_object
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=8, y_subdivisions=8, size=2.0, location=(0.0, 0.0, 1.0))
    roof = bpy.context.active_object
    if mirrored:
        roof.scale = (-1.0, 1.0, 1.0)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    cam.data.lens = 12.0  # (wide: the camera under the roof is 0.8 from it)
    scene.camera = cam
    scene.prt_display.albedo_source = "WHITE"
    return floor, roof, cam


def _at_vertices(bpy, scene, cam, obj, image):
    """The image's pixels at obj's vertices (those inside the frame, not at its edge), and which."""
    p = np.array([obj.matrix_world @ v.co for v in obj.data.vertices])
    depsgraph = bpy.context.evaluated_depsgraph_get()
    proj = np.array(cam.calc_matrix_camera(depsgraph, x=SIZE, y=SIZE)) @ np.array(cam.matrix_world.inverted())
    clip = np.c_[p, np.ones(len(p))] @ proj.T
    ndc = clip[:, :2] / clip[:, 3:4]
    cols = np.floor((ndc[:, 0] + 1) * 0.5 * SIZE).astype(int)
    rows = np.floor((1 - ndc[:, 1]) * 0.5 * SIZE).astype(int)
    inside = (cols >= 2) & (cols < SIZE - 2) & (rows >= 2) & (rows < SIZE - 2)
    return image[rows[inside], cols[inside], :3], inside


@pytest.mark.parametrize(("order", "mirrored"), [(4, False), (6, False), (4, True)])
def test_roof_from_above_and_below_draws_each_side_as_shade(bpy_module, empty_scene, order, mirrored):
    """Order 4 draws the transfer from vertex attributes (front and back: 8 vec4s), order 6 from
    the transfer texture (18 vec4s); a mirrored roof turns gl_FrontFacing over and must not
    swap the sides. From below the roof sees the floor and no sun, from above the sky and the sun."""
    from prt_addon.blender.display import offscreen

    assert offscreen.ensure_gpu()
    bpy = bpy_module
    floor, roof, cam = _scene(bpy, empty_scene, mirrored)
    api.project_world(empty_scene, order, split_lights=True)
    assert api.world_lights(empty_scene)
    api.bake([floor, roof], order=order, samples=256)
    results = {}
    for side, location, euler in (
        ("FRONT", (0.0, 0.0, 4.0), (0.0, 0.0, 0.0)),
        ("BACK", (0.0, 0.0, 0.3), (math.pi, 0.0, 0.0)),
    ):
        cam.location, cam.rotation_euler = location, euler
        bpy.context.view_layer.update()
        image = api.render_view(empty_scene, SIZE, SIZE)
        got, inside = _at_vertices(bpy, empty_scene, cam, roof, image)
        want = api.shade(roof, empty_scene, side=side)[inside]
        assert inside.sum() >= 25
        results[side] = (float(np.median(np.abs(got - want) / (np.abs(want) + 0.05))), float(got.mean()))
    print(f"\norder {order}, mirrored {mirrored}: {results}")
    assert results["BACK"][1] < 0.3 * results["FRONT"][1]  # the underside is drawn dark
    # The sun's shadow is a map here and traced in shade (docs/display.md, "Sun shadows"); the
    # roof's top is unshadowed and its underside faces away from the sun.
    assert results["FRONT"][0] < 0.02 and results["BACK"][0] < 0.02
