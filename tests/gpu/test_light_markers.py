"""Light-direction markers: drawn along each split light's projected direction, in its colour,
following the Mapping rotation live, and absent when the setting is off. Needs the GPU headless."""

import math

import numpy as np
import pytest
from helpers.display_scenes import add_camera
from helpers.worlds import image_world, sunny_image

SIZE = 256
SUN_COLOUR = np.array([1.0, 0.9, 0.7])  # sunny_image's patch


@pytest.fixture
def sun_scene(bpy_module, empty_scene, gpu_ready):
    """A sky with one bright patch, projected with the split; a camera looking straight down on
    the 3D cursor at the origin; no baked object (the markers need none)."""
    from prt_addon import api

    scene = empty_scene
    _, mapping = image_world(bpy_module, scene, sunny_image(64, 128), euler=(0.0, 0.0, 0.0))
    api.project_world(scene, 4, split_lights=True)
    assert len(api.world_lights(scene)) == 1
    add_camera(bpy_module, scene, location=(0.0, 0.0, 12.0), euler=(0.0, 0.0, 0.0), size=SIZE)
    scene.cursor.location = (0.0, 0.0, 0.0)
    bpy_module.context.view_layer.update()
    return scene, mapping


def pixels_of(scene, points):
    """(rows, cols) of world points in the SIZE x SIZE camera image, top row 0."""
    from prt_addon.blender.display import offscreen

    view, proj = offscreen.camera_matrices(scene, SIZE, SIZE)
    clip = np.c_[points, np.ones(len(points))] @ (proj @ view).T
    ndc = clip[:, :2] / clip[:, 3:4]
    return (
        np.floor((1.0 - ndc[:, 1]) * 0.5 * SIZE).astype(int),
        np.floor((ndc[:, 0] + 1.0) * 0.5 * SIZE).astype(int),
    )


def along(direction, length, fractions=np.linspace(0.15, 0.85, 15)):
    return np.outer(fractions, length * np.asarray(direction))


def render(scene):
    from prt_addon import api

    return api.render_view(scene, SIZE, SIZE)


def marker_length(scene):
    from prt_addon.blender.display import light_markers

    return light_markers.LENGTH_SCALE * float(np.linalg.norm(np.array(scene.camera.location)))


def drawn_on(image, scene, points):
    """Fraction of the points whose pixel (or a neighbour) is drawn, and the drawn pixels' RGB."""
    rows, cols = pixels_of(scene, points)
    hit, colours = 0, []
    for r, c in zip(rows, cols):
        patch = image[max(r - 1, 0) : r + 2, max(c - 1, 0) : c + 2].reshape(-1, 4)
        best = patch[np.argmax(patch[:, 3])]
        if best[3] > 0.5:
            hit += 1
            colours.append(best[:3] / best[3])
    return hit / len(points), np.array(colours)


def test_marker_lies_along_the_light_in_its_colour_and_only_when_on(bpy_module, sun_scene):
    from prt_addon import api

    scene, _mapping = sun_scene
    direction = api.world_lights(scene)[0]["direction"]
    assert abs(direction[2]) < 0.9  # the line has a long projection in the top view
    scene.prt_display.show_light_directions = False
    off = render(scene)
    assert off[..., 3].max() == 0.0  # nothing baked, no markers: an empty picture
    scene.prt_display.show_light_directions = True
    on = render(scene)
    fraction, colours = drawn_on(on, scene, along(direction, marker_length(scene)))
    assert fraction == 1.0
    np.testing.assert_allclose(
        colours / colours[:, :1], np.tile(SUN_COLOUR / SUN_COLOUR[0], (len(colours), 1)), atol=0.03
    )
    # Opposite the light and off the line: nothing.
    assert drawn_on(on, scene, along(-direction, marker_length(scene)))[0] == 0.0
    side = np.cross(direction, [0.0, 0.0, 1.0])
    assert drawn_on(on, scene, along(side / np.linalg.norm(side), marker_length(scene)))[0] == 0.0
    scene.prt.show_display = False  # the whole PRT display off: no markers either
    assert render(scene)[..., 3].max() == 0.0


def test_marker_follows_the_mapping_rotation_live(bpy_module, sun_scene):
    from prt_addon import api

    scene, mapping = sun_scene
    scene.prt_display.show_light_directions = True
    before = api.world_lights(scene)[0]["direction"]
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(90.0))
    after = api.world_lights(scene)[0]["direction"]
    # A turn about Z by 90 degrees turns the light's direction by 90 degrees about Z (either sense).
    np.testing.assert_allclose(after[2], before[2], atol=1e-6)  # (the node holds float32)
    assert abs(np.dot(after[:2], before[:2])) < 1e-6
    image = render(scene)  # no new projection: the marker follows the node now
    length = marker_length(scene)
    assert drawn_on(image, scene, along(after, length))[0] == 1.0
    assert drawn_on(image, scene, along(before, length, np.linspace(0.4, 0.85, 8)))[0] == 0.0


def test_circle_has_the_angular_radius_seen_from_the_cursor():
    from prt_addon.blender.display import light_markers
    from prt_addon.core.lights.extraction import Light

    lights = [Light([0.0, 0.6, 0.8], [4.0, 2.0, 1.0], math.radians(5.0)), Light([1.0, 0.0, 0.0], [1.0, 1.0, 1.0], 0.0)]
    centre = np.array([1.0, -2.0, 0.5])
    (line, circle, colour, width), (_l2, circle2, colour2, width2) = light_markers.marker_segments(lights, centre, 3.0)
    np.testing.assert_allclose(line, [centre, centre + 3.0 * np.array([0.0, 0.6, 0.8])], atol=1e-12)
    seen = (circle - centre) / np.linalg.norm(circle - centre, axis=1, keepdims=True)
    np.testing.assert_allclose(np.degrees(np.arccos(seen @ [0.0, 0.6, 0.8])), 5.0, atol=1e-9)
    np.testing.assert_allclose(circle[0], circle[-1], atol=1e-12)  # a closed loop
    np.testing.assert_allclose(circle2, np.tile(centre + [3.0, 0.0, 0.0], (len(circle2), 1)), atol=1e-12)
    assert colour == (1.0, 0.5, 0.25, 1.0)
    assert colour2 == (1.0, 1.0, 1.0, 1.0)
    assert width > width2  # the strongest light's line is the widest


def test_viewport_handler_lives_with_the_draw_handler(bpy_module, addon):
    from prt_addon.blender.display import draw, light_markers

    assert draw.draw_handle() is not None
    assert light_markers._handle is not None
    draw.remove_draw_handler()
    try:
        assert light_markers._handle is None
    finally:
        draw.add_draw_handler()
    assert light_markers._handle is not None
