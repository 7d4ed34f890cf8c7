"""The Principled specular in render_view: the white furnace, and reflections that turn with the lighting."""

import math

import numpy as np
import pytest
from helpers.display_scenes import add_camera, bake_sphere
from helpers.specular_scenes import principled_material
from helpers.worlds import image_world, new_world


def _principled(bpy, obj, base=(1.0, 1.0, 1.0), roughness=0.5, metallic=0.0):
    obj.data.materials.clear()
    obj.data.materials.append(principled_material(bpy, "Principled", base, roughness, metallic))


def _sphere_pixels(image, min_alpha=0.5):
    return image[..., :3][image[..., 3] > min_alpha]


@pytest.fixture
def furnace(bpy_module, empty_scene, gpu_ready):
    from prt_addon.blender.world import projection

    scene = empty_scene
    scene.prt_display.specular = True
    new_world(bpy_module, scene, (1.0, 1.0, 1.0), 1.0)
    add_camera(bpy_module, scene, size=96)
    projection.project_and_store(scene, 4)
    obj = bake_sphere(bpy_module, 4, segments=64, rings=32)
    return scene, obj


@pytest.mark.parametrize("metallic", [0.0, 1.0])
def test_white_furnace_in_render_view(bpy_module, furnace, metallic):
    """A white metal and a white dielectric sphere under a uniform white world give 1 within 3 %
    at roughness 0.1 to 1, pixel by pixel (the silhouette's last pixels left out)."""
    import prt_addon.api as api

    scene, obj = furnace
    scene.prt_display.specular = False
    _principled(bpy_module, obj, roughness=0.5, metallic=metallic)
    diffuse = _sphere_pixels(api.render_view(scene))
    scene.prt_display.specular = True
    # Diffuse only, a metal is drawn as white chalk too: the furnace alone does not show the lobe.
    assert np.allclose(diffuse, 1.0, atol=0.01)
    for roughness in (0.1, 0.3, 0.6, 1.0):
        _principled(bpy_module, obj, roughness=roughness, metallic=metallic)
        pixels = _sphere_pixels(api.render_view(scene), 0.99)
        assert len(pixels) > 1000
        assert np.abs(pixels - 1.0).max() < 0.03, (roughness, pixels.min(), pixels.max())


def test_specular_changes_a_coloured_metal(bpy_module, furnace):
    """Under the same white world a gold metal reflects its base colour at normal incidence and
    whiter light at grazing angles (Schlick), which the diffuse-only draw cannot show."""
    import prt_addon.api as api

    scene, obj = furnace
    gold = (1.0, 0.6, 0.2)
    _principled(bpy_module, obj, base=gold, roughness=0.3, metallic=1.0)
    image = api.render_view(scene)
    h, w = image.shape[:2]
    centre = image[h // 2, w // 2, :3]
    assert np.allclose(centre, gold, atol=0.04)
    rim = _sphere_pixels(image, 0.99)
    assert rim[:, 2].max() > gold[2] + 0.15  # grazing pixels tend to white


def _highlight(image):
    lum = image[..., :3] @ np.array([0.2126, 0.7152, 0.0722])
    row, col = np.unravel_index(np.argmax(lum), lum.shape)
    return row, col


def _predicted_highlight(bpy, scene, sun_world, size):
    """The pixel of the mirror point of a distant light on a unit sphere at the origin seen from
    the camera: the normal halfway between the light and the camera."""
    cam = scene.camera
    eye = np.array(cam.matrix_world.translation)
    n = sun_world + eye / np.linalg.norm(eye)
    n /= np.linalg.norm(n)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    proj = np.array(cam.calc_matrix_camera(depsgraph, x=size, y=size))
    clip = proj @ np.array(cam.matrix_world.inverted()) @ np.r_[n, 1.0]
    ndc = clip[:3] / clip[3]
    return (1.0 - ndc[1]) * 0.5 * size, (ndc[0] + 1.0) * 0.5 * size


def test_rotation_turns_the_highlight(bpy_module, empty_scene, gpu_ready):
    """A small bright patch in the sky, no split: a glossy metal sphere's highlight sits where
    the mirror reflection of that patch is, before and after turning the lighting."""
    import prt_addon.api as api
    from prt_addon.blender.world import nodes, projection
    from prt_addon.core.sh import projection as sh_projection

    scene = empty_scene
    scene.prt_display.specular = True
    height, width = 64, 128
    rgb = np.full((height, width, 3), 0.05)
    row, col = 40, 20  # the patch's pixel (row 0 at the bottom)
    rgb[row, col] = 2000.0
    world, mapping = image_world(bpy_module, scene, rgb, euler=(0.0, 0.0, 0.0))
    scene.prt_world.split_lights = False
    size = 160
    add_camera(bpy_module, scene, size=size)
    projection.project_and_store(scene, 4, split_lights=False)
    obj = bake_sphere(bpy_module, 4, segments=96, rings=48)
    _principled(bpy_module, obj, base=(1.0, 1.0, 1.0), roughness=0.1, metallic=1.0)
    s_image = sh_projection.pixel_directions(height, width)[row, col]
    seen = []
    for turn in (0.0, 0.5, -0.7):
        mapping.inputs["Rotation"].default_value = (0.0, 0.0, turn)
        q = nodes.live_sh_rotation(world)
        image = api.render_view(scene)
        got = np.array(_highlight(image), dtype=float) + 0.5
        expected = np.array(_predicted_highlight(bpy_module, scene, q @ s_image, size))
        assert np.linalg.norm(got - expected) < 3.0, (turn, got, expected)
        seen.append(got)
    assert np.linalg.norm(seen[0] - seen[1]) > 10.0 and np.linalg.norm(seen[0] - seen[2]) > 10.0
    assert math.isfinite(float(image[..., :3].sum()))


@pytest.mark.parametrize("order", [1, 4, 8, 12])
@pytest.mark.parametrize("lights", [None, (1, 0), (1, 2)])
def test_specular_shader_compiles_for_every_path(gpu_ready, order, lights):
    """Vertex attributes (orders <= 7) or the transfer texture, with and without split lights
    (compact and wide views), bounced bakes and texel bakes."""
    from prt_addon.blender.display import shader as display_shader
    from prt_addon.blender.scene import storage

    count = storage.attribute_count(order)
    for channels, domain in ((0, "POINT"), (3, "POINT"), (0, "TEXEL")):
        assert display_shader.get_shader(count, lights, channels, domain, specular=True) is not None
