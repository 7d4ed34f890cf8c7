"""World lighting projection: constant worlds, images of known coefficients, Mapping rotation; shared helpers.

Expectations are independent of the code under test where possible: exact constants, analytic
integrals over half spheres, pixel-exact column shifts for 90-degree turns, and images synthesised
from known coefficients. The Mapping convention (world seen along D = image(R D) for POINT, VECTOR
and NORMAL, image(R^-1 D) for TEXTURE) was measured with Cycles; tests/cycles/test_world_cycles.py checks
it against Cycles again. Image formats, bad input, memory and storage: tests/blender/test_world_images.py.
"""

import math

import numpy as np
import pytest
from helpers.worlds import SQRT_4PI, add_mapping, float_image, image_of, known_coeffs, new_world, use_image

from prt_addon.core.sh import projection, rotation


def project_image(bpy, scene, rgb, order, **mapping):
    world = scene.world or new_world(bpy, scene)
    env = use_image(world, float_image(bpy, "img", rgb))
    if mapping:
        add_mapping(world, env, **mapping)
    from prt_addon import api

    return api.project_world(scene, order)


# --- constants --------------------------------------------------------------------------------


def test_constant_colour_world_is_exact(bpy_module, empty_scene):
    from prt_addon import api

    new_world(bpy_module, empty_scene, color=(0.2, 0.5, 1.5), strength=2.5)
    c = api.project_world(empty_scene, 5)
    assert c.shape == (25, 3)
    np.testing.assert_allclose(c[0], SQRT_4PI * 2.5 * np.array([0.2, 0.5, 1.5]), rtol=1e-6)
    assert np.all(c[1:] == 0.0)
    settings = empty_scene.prt_world
    assert settings.stored_order == 5
    assert settings.source_kind == "COLOR"
    assert settings.truncation == 0.0
    assert settings.seconds > 0.0


@pytest.mark.parametrize("size", [(1, 1), (7, 3), (300, 150)])
def test_constant_image_is_exact_at_any_size(bpy_module, empty_scene, size):
    width, height = size
    rgb = np.broadcast_to(np.array([0.25, 1.0, 3.0]), (height, width, 3))
    c = project_image(bpy_module, empty_scene, rgb, 4)
    np.testing.assert_allclose(c[0], SQRT_4PI * np.array([0.25, 1.0, 3.0]), rtol=1e-6)
    np.testing.assert_allclose(c[1:], 0.0, atol=1e-6)


def test_two_pixel_image_halves_are_the_y_hemispheres(bpy_module, empty_scene):
    """Column 0 of a 2x1 image is azimuth 0..pi, i.e. y > 0 (u = -atan2(y, x)/2pi + 1/2).

    c_0 = sqrt(4 pi) (a + b) / 2 and c_{1,-1} = sqrt(3 / 4 pi) * integral_{y>0} y dOmega * (a - b)
    = sqrt(3 / 4 pi) pi (a - b); c_{1,0} = c_{1,1} = 0.
    """
    a, b = 3.0, 1.0
    rgb = np.array([[[a] * 3, [b] * 3]])
    c = project_image(bpy_module, empty_scene, rgb, 2)
    np.testing.assert_allclose(c[0], SQRT_4PI * (a + b) / 2, rtol=1e-6)
    np.testing.assert_allclose(c[1], math.sqrt(3 / (4 * math.pi)) * math.pi * (a - b), rtol=1e-6)
    np.testing.assert_allclose(c[2:], 0.0, atol=1e-6)


# --- images of known coefficients ----------------------------------------------------------------


@pytest.mark.parametrize("size", [(512, 256), (300, 150)])
def test_image_of_known_coefficients_gives_them_back(bpy_module, empty_scene, size):
    """A band-limited image sampled at pixel centres projects back to its coefficients up to the
    sampling error, (pi / H)^2 l^2 / 24 relative in band l: under 4e-4 at H = 150, l = 5."""
    width, height = size
    c = known_coeffs(6)
    out = project_image(bpy_module, empty_scene, image_of(c, height, width), 6)
    np.testing.assert_allclose(out, c, atol=4e-4 * np.abs(c).max())
    # And bit-for-bit what the core makes of the same float32 pixels.
    core, _ = projection.project_equirect(image_of(c, height, width).astype(np.float32), 6)
    np.testing.assert_allclose(out, core, rtol=1e-9, atol=1e-12)


def test_strength_scales_the_coefficients(bpy_module, empty_scene):
    from prt_addon import api

    c = known_coeffs(4)
    world = new_world(bpy_module, empty_scene)
    use_image(world, float_image(bpy_module, "img", image_of(c, 64, 128)), strength=3.0)
    out3 = api.project_world(empty_scene, 4)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
    np.testing.assert_allclose(out3, 3.0 * api.project_world(empty_scene, 4), rtol=1e-12)


# --- Mapping rotation -----------------------------------------------------------------------------


@pytest.mark.parametrize("vector_type", ["POINT", "VECTOR", "TEXTURE"])
def test_mapping_zero_and_quarter_turn_about_z_match_shifted_image(bpy_module, empty_scene, vector_type):
    """90 degrees about Z shifts the image by W/4 columns exactly: for POINT/VECTOR the world at
    azimuth phi is the image at phi + 90 deg, i.e. column k - W/4 (TEXTURE: the other way)."""
    c = known_coeffs(6)
    height, width = 64, 128
    rgb = image_of(c, height, width)
    plain = project_image(bpy_module, empty_scene, rgb, 6)
    zero = project_image(bpy_module, empty_scene, rgb, 6, euler=(0, 0, 0), vector_type=vector_type)
    np.testing.assert_allclose(zero, plain, rtol=0, atol=1e-12)
    shift = width // 4 if vector_type != "TEXTURE" else -width // 4
    expected = project_image(bpy_module, empty_scene, np.roll(rgb, shift, axis=1), 6)
    turned = project_image(bpy_module, empty_scene, rgb, 6, euler=(0, 0, math.radians(90)), vector_type=vector_type)
    np.testing.assert_allclose(turned, expected, atol=1e-7 * np.abs(c).max())  # float32 pixels
    # The opposite turn is far from it (so the comparison can fail).
    wrong = project_image(bpy_module, empty_scene, np.roll(rgb, -shift, axis=1), 6)
    assert np.abs(turned - wrong).max() > 0.1


@pytest.mark.parametrize(
    ("euler", "vector_type"),
    [
        ((0.0, 0.0, 37.0), "POINT"),
        ((0.0, 0.0, 37.0), "TEXTURE"),
        ((90.0, 0.0, 0.0), "POINT"),
        ((-30.0, 0.0, 0.0), "VECTOR"),
        ((20.0, -35.0, 110.0), "POINT"),
    ],
)
def test_mapping_rotation_matches_projecting_a_rotated_image(bpy_module, empty_scene, euler, vector_type):
    """Mapping rotation R, applied as an SH rotation, against projecting the image of f(R d)
    (f(R^-1 d) for TEXTURE) with no Mapping. Both are samplings of the same band-limited
    function, so they agree to the sampling error (< 4e-4 relative at H = 128, order 6)."""
    c = known_coeffs(6)
    height, width = 128, 256
    r = rotation.euler_xyz_matrix(np.radians(euler))
    lookup = r if vector_type != "TEXTURE" else r.T
    expected = project_image(bpy_module, empty_scene, image_of(c, height, width, lookup), 6)
    out = project_image(
        bpy_module,
        empty_scene,
        image_of(c, height, width),
        6,
        euler=tuple(np.radians(euler)),
        vector_type=vector_type,
    )
    scale = np.abs(c).max()
    np.testing.assert_allclose(out, expected, atol=4e-4 * scale)
    settings = empty_scene.prt_world
    assert settings.mapping_node
    assert settings.mapping_type == vector_type
    # The stored coefficients are the unrotated ones.
    from prt_addon.blender.world import projection as world_projection

    np.testing.assert_allclose(world_projection.stored_image_coeffs(empty_scene), c, atol=4e-4 * scale)
    # The inverse rotation is rejected by the same tolerance.
    wrong = project_image(bpy_module, empty_scene, image_of(c, height, width, lookup.T), 6)
    assert np.abs(out - wrong).max() > 20 * 4e-4 * scale


def test_current_world_coeffs_follow_the_mapping_without_reprojecting(bpy_module, empty_scene):
    from prt_addon import api
    from prt_addon.blender.world import projection as world_projection

    assert world_projection.current_world_coeffs(empty_scene) is None
    c = known_coeffs(5)
    world = new_world(bpy_module, empty_scene)
    env = use_image(world, float_image(bpy_module, "img", image_of(c, 64, 128)))
    mapping = add_mapping(world, env, euler=(0.0, 0.0, 0.4))
    first = api.project_world(empty_scene, 5)
    np.testing.assert_allclose(api.world_lighting(empty_scene), first, atol=1e-12)
    token = empty_scene.prt_world.token
    stored = np.array(empty_scene[world_projection.SH_KEY])

    mapping.inputs["Rotation"].default_value = (0.3, -0.2, 1.7)
    live = world_projection.current_world_coeffs(empty_scene)
    assert empty_scene.prt_world.token == token  # nothing was projected again
    np.testing.assert_array_equal(np.array(empty_scene[world_projection.SH_KEY]), stored)
    # Same as a full projection with the new rotation.
    np.testing.assert_allclose(live, api.project_world(empty_scene, 5), atol=1e-10)
    assert np.abs(live - first).max() > 0.1


def test_mapping_location_or_non_uniform_scale_is_not_ignored(bpy_module, empty_scene):
    from prt_addon.blender.world import nodes as world_nodes

    world = new_world(bpy_module, empty_scene)
    env = use_image(world, float_image(bpy_module, "img", np.ones((8, 16, 3))))
    mapping = add_mapping(world, env, euler=(0, 0, 1.0))
    mapping.inputs["Scale"].default_value = (2.0, 2.0, 2.0)  # uniform: no effect (normalised)
    assert world_nodes.analyse_world(empty_scene).kind == "IMAGE"
    mapping.inputs["Location"].default_value = (0.0, 0.5, 0.0)
    source = world_nodes.analyse_world(empty_scene)
    assert source.kind == "RENDER"
    assert "location" in source.reason
    mapping.vector_type = "VECTOR"  # a vector mapping ignores location
    assert world_nodes.analyse_world(empty_scene).kind == "IMAGE"
    mapping.inputs["Scale"].default_value = (1.0, 1.0, -1.0)
    source = world_nodes.analyse_world(empty_scene)
    assert source.kind == "RENDER"
    assert "scale" in source.reason
