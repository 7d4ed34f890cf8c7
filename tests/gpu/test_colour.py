"""The overlay's colour management: render_view(display=True) against Blender's own pipeline.

The independent expectation is the linear render_view image pushed through Image.save_render
(the scene's view transform, look, exposure, gamma) into an 8-bit PNG, i.e. what Blender itself
writes for those radiances; the display image comes from the PRT shader's table lookup.
"""

import numpy as np
import pytest
from helpers.display_scenes import add_camera, add_env_world, bake_sphere, set_light, sun_sky_light

SIZE = 128
EXPOSURE = 0.7
GAMMA = 1.3
MEAN_LIMIT = 2.0  # /255, over the drawn pixels
APPROXIMATE = {"False Color"}  # discontinuous bands: a table blurs their edges (docs/display.md)


def enum_choices(owner, name):
    """The identifiers a dynamic enum accepts here (its static list is empty in bpy)."""
    try:
        setattr(owner, name, "__no_such_item__")
    except TypeError as exc:
        text = str(exc)
        return [item.strip().strip("'\"") for item in text[text.rindex("(") + 1 : text.rindex(")")].split(",")]
    raise AssertionError(f"{name} accepted a bogus value")


@pytest.fixture
def colour_scene(bpy_module, empty_scene, gpu_ready):
    """A sphere under a warm sun and a blue sky: radiances from 0.1 to about 2, in colour."""
    scene = empty_scene
    add_env_world(bpy_module, scene)
    add_camera(bpy_module, scene, location=(0.0, -3.5, 0.0), size=SIZE)
    bake_sphere(bpy_module, 4, segments=32, rings=16)
    set_light(scene, sun_sky_light(4))
    scene.prt_display.albedo_source = "WHITE"
    view = scene.view_settings
    view.exposure, view.gamma, view.look = EXPOSURE, GAMMA, "None"
    return scene


def blender_display(bpy, scene, linear, path):
    """Blender's own display image of a linear render: save_png (save_render, 8-bit) read back."""
    import prt_addon.api as api

    api.save_png(linear, path, scene)
    image = bpy.data.images.load(path)
    image.colorspace_settings.name = "Non-Color"  # the stored values, not decoded
    pixels = np.empty(SIZE * SIZE * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    bpy.data.images.remove(image)
    return pixels.reshape(SIZE, SIZE, 4)[::-1, :, :3]


def differences(bpy, scene, tmp_path):
    """(|display - Blender's|) * 255 over the drawn pixels, and the linear image."""
    import prt_addon.api as api

    linear = api.render_view(scene, SIZE, SIZE)
    shown = api.render_view(scene, SIZE, SIZE, display=True)
    expected = blender_display(bpy, scene, linear, str(tmp_path / "blender.png"))
    drawn = linear[..., 3] > 0
    assert drawn.sum() > 3000
    np.testing.assert_array_equal(shown[..., 3], linear[..., 3])
    return np.abs(shown[drawn, :3] - expected[drawn]) * 255.0, linear[drawn, :3]


def test_every_view_transform_matches_blenders_own(bpy_module, colour_scene, tmp_path, capsys):
    """Each view transform the config offers for the sRGB display, exposure 0.7, gamma 1.3: mean
    difference at most 2/255 over the drawn pixels (the maximum is printed)."""
    scene = colour_scene
    assert scene.display_settings.display_device == "sRGB"
    transforms = enum_choices(scene.view_settings, "view_transform")
    for required in ("Standard", "AgX", "Filmic", "Khronos PBR Neutral"):
        assert required in transforms, transforms
    rows = []
    for transform in transforms:
        scene.view_settings.view_transform = transform
        scene.view_settings.look = "None"
        diff, linear = differences(bpy_module, scene, tmp_path)
        rows.append((transform, diff.mean(), diff.max()))
        if transform not in APPROXIMATE:
            assert diff.mean() <= MEAN_LIMIT, (transform, diff.mean(), diff.max())
    assert linear.max() * 2**EXPOSURE > 2.0
    assert linear.min() < 0.2
    with capsys.disabled():
        print(f"\nexposure {EXPOSURE}, gamma {GAMMA}: |render_view(display=True) - save_render| / 255")
        for transform, mean, top in rows:
            print(f"  {transform:24s} mean {mean:5.2f}  max {top:5.2f}")


def test_looks_curves_and_white_balance_carry(bpy_module, colour_scene, tmp_path, capsys):
    """A Look, a curve-mapping edit and (Blender 4.5+) white balance go through the same table."""
    scene = colour_scene
    view = scene.view_settings
    view.view_transform = "AgX"
    looks = [look for look in enum_choices(view, "look") if look != "None"]
    cases = [("look " + looks[0], lambda: setattr(view, "look", looks[0]))] if looks else []

    def curve():
        view.look = "None"
        view.use_curve_mapping = True
        view.curve_mapping.curves[3].points[1].location = (1.0, 0.7)
        view.curve_mapping.update()

    cases.append(("curve mapping", curve))
    if hasattr(view, "use_white_balance"):

        def white_balance():
            view.use_curve_mapping = False
            view.use_white_balance = True
            view.white_balance_temperature = 4500.0

        cases.append(("white balance 4500 K", white_balance))
    plain, _ = differences(bpy_module, scene, tmp_path)
    for name, change in cases:
        change()
        diff, _ = differences(bpy_module, scene, tmp_path)
        assert diff.mean() <= MEAN_LIMIT, (name, diff.mean(), diff.max())
        with capsys.disabled():
            print(f"\n  AgX + {name}: mean {diff.mean():.2f} max {diff.max():.2f} /255")
    assert plain.mean() <= MEAN_LIMIT


def test_linear_render_ignores_colour_management(bpy_module, colour_scene):
    """display=False stays today's linear radiance, whatever the view settings."""
    import prt_addon.api as api

    scene = colour_scene
    scene.view_settings.view_transform = "AgX"
    agx = api.render_view(scene, SIZE, SIZE)
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.exposure, scene.view_settings.gamma = 0.0, 1.0
    np.testing.assert_array_equal(api.render_view(scene, SIZE, SIZE), agx)


def test_viewport_follows_setting_changes_without_building_while_drawing(bpy_module, colour_scene, monkeypatch):
    """The draw callback never builds a table: after a change it draws with the last one until
    the timer (run here by hand; no event loop in bpy) has built the new one, then it draws exactly
    what render_view(display=True) draws. The timer is registered with the add-on."""
    import types

    import bpy
    import gpu
    import mathutils

    import prt_addon.api as api
    from prt_addon.blender.display import colour, draw as display_draw, offscreen

    assert bpy.app.timers.is_registered(colour._check)
    scene = colour_scene
    scene.view_settings.view_transform = "AgX"
    agx = api.render_view(scene, SIZE, SIZE, display=True)
    view, proj = offscreen.camera_matrices(scene, SIZE, SIZE)
    context = types.SimpleNamespace(
        scene=scene,
        region_data=types.SimpleNamespace(perspective_matrix=mathutils.Matrix((proj @ view).tolist())),
        view_layer=bpy_module.context.view_layer,
        space_data=None,
        evaluated_depsgraph_get=bpy_module.context.evaluated_depsgraph_get,
    )

    def viewport_frame():
        off = gpu.types.GPUOffScreen(SIZE, SIZE, format="RGBA32F")
        with off.bind():
            fb = gpu.state.active_framebuffer_get()
            fb.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
            display_draw.draw_viewport(context)
            img = np.asarray(fb.read_color(0, 0, SIZE, SIZE, 4, 0, "FLOAT")).T.reshape(SIZE, SIZE, 4)[::-1].copy()
        off.free()
        img[..., :3] = colour.encode_display(img[..., :3])  # as the overlay's sRGB framebuffer stores it
        return img

    drawn = agx[..., 3] > 0
    np.testing.assert_allclose(viewport_frame()[drawn], agx[drawn], atol=1e-6)
    scene.view_settings.view_transform = "Filmic"
    scene.view_settings.gamma = 0.8
    real_build = colour.build_table

    def refuse(*_args, **_kw):
        raise AssertionError("a table was built while drawing")

    monkeypatch.setattr(colour, "build_table", refuse)
    np.testing.assert_allclose(viewport_frame()[drawn], agx[drawn], atol=1e-6)  # still the last table
    monkeypatch.setattr(colour, "build_table", real_build)
    assert colour._check() == colour.CHECK_INTERVAL  # (bpy.context.scene is the scene here)
    filmic = api.render_view(scene, SIZE, SIZE, display=True)
    assert np.abs(filmic[drawn, :3] - agx[drawn, :3]).mean() > 0.02  # the change is visible
    np.testing.assert_allclose(viewport_frame()[drawn], filmic[drawn], atol=1e-6)


def test_table_black_and_grey(bpy_module, colour_scene):
    """Node 0 is exactly black and maps to black; middle grey under Standard is its sRGB code."""
    from prt_addon.blender.display import colour

    scene = colour_scene
    view = scene.view_settings
    view.view_transform, view.gamma = "Standard", 1.0
    table = colour.build_table(scene, 17)
    values = colour.node_values(17)
    assert values[0] == 0.0
    assert np.all(table[0, 0, 0] == 0.0)
    grey = int(np.argmin(np.abs(values - 0.18)))
    x = values[grey]
    expected = 1.055 * x ** (1 / 2.4) - 0.055  # the sRGB code of that node
    np.testing.assert_allclose(table[grey, grey, grey], expected, atol=1.0 / 65535 + 1e-6)
