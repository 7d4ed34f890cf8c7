"""World projection of real images: 8-bit and EXR files, bad pixels, memory, reduction, errors, saving."""

import os
import tracemalloc

import numpy as np
import pytest
from helpers.worlds import SQRT_4PI, add_mapping, float_image, image_of, known_coeffs, new_world, use_image

from prt_addon.core.sh import projection, resample

# --- image formats and bad input -----------------------------------------------------------------


def srgb_to_linear(v):
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def test_8bit_srgb_image_is_linearised(bpy_module, empty_scene):
    from prt_addon import api

    world = new_world(bpy_module, empty_scene)
    image = bpy_module.data.images.new("byte", 16, 8)  # 8-bit, colour space sRGB
    assert not image.is_float
    assert image.colorspace_settings.name == "sRGB"
    encoded = np.array([64, 128, 230]) / 255.0
    image.pixels.foreach_set(np.tile(np.append(encoded, 1.0), 16 * 8).astype(np.float32))
    use_image(world, image)
    c = api.project_world(empty_scene, 3)
    np.testing.assert_allclose(c[0], SQRT_4PI * srgb_to_linear(encoded), rtol=2e-4)
    data = bpy_module.data.images.new("data", 16, 8)
    data.colorspace_settings.name = "Non-Color"  # data: used as stored
    data.pixels.foreach_set(np.tile(np.append(encoded, 1.0), 16 * 8).astype(np.float32))
    use_image(world, data)
    c = api.project_world(empty_scene, 3)
    np.testing.assert_allclose(c[0], SQRT_4PI * encoded, rtol=1e-6)


def test_packed_and_saved_exr_images(bpy_module, empty_scene, tmp_path):
    from prt_addon import api

    c = known_coeffs(4)
    rgb = image_of(c, 32, 64)
    image = float_image(bpy_module, "src", rgb)
    path = str(tmp_path / "env.exr")
    image.filepath_raw = path
    image.file_format = "OPEN_EXR"
    if bpy_module.app.version < (5, 0, 0):  # Blender 4.x Image.save() otherwise display-encodes
        image.colorspace_settings.is_data = True
    image.save()
    bpy_module.data.images.remove(image)

    world = new_world(bpy_module, empty_scene)
    loaded = bpy_module.data.images.load(path)
    use_image(world, loaded)
    from_file = api.project_world(empty_scene, 4)
    np.testing.assert_allclose(from_file, c, atol=3e-3 * np.abs(c).max())  # half-float EXR
    loaded.pack()
    os.remove(path)
    loaded.reload()
    np.testing.assert_allclose(api.project_world(empty_scene, 4), from_file, atol=1e-12)


def test_bad_pixels_are_repaired_and_reported(bpy_module, empty_scene):
    from prt_addon.blender.world import projection as world_projection

    rgb = np.full((16, 32, 3), 2.0)
    rgb[3, 5] = (np.nan, 1.0, 1.0)
    rgb[8, 9] = (np.inf, -np.inf, 1.0)
    rgb[10, 30] = (-5.0, 2.0, 2.0)
    world = new_world(bpy_module, empty_scene)
    use_image(world, float_image(bpy_module, "bad", rgb))
    result = world_projection.project(empty_scene, 3)
    repaired = np.nan_to_num(rgb, nan=0.0, posinf=0.0, neginf=0.0).clip(0.0, None)
    expected, _ = projection.project_equirect(repaired, 3)
    np.testing.assert_allclose(result.coeffs, expected, rtol=1e-6, atol=1e-9)
    said = "; ".join(result.warnings)
    assert "1 HDRI value was negative and treated as black" in said, said
    assert "3 HDRI values were not a number (NaN or infinite) and treated as black" in said, said
    bpy_module.ops.prt.project_world(order=3)  # warnings do not make the operator fail


def test_negative_values_alone_are_told_in_the_report_not_as_a_warning(bpy_module, empty_scene):
    """An HDRI with a few small negative values (as compressed HDRIs have) needs nothing of the
    user: the operator's report says what was done, the panel shows no warning."""
    from prt_addon.blender.world import projection as world_projection

    rgb = np.full((16, 32, 3), 2.0)
    rgb[10, 30] = (-0.01, 2.0, 2.0)
    world = new_world(bpy_module, empty_scene)
    use_image(world, float_image(bpy_module, "slightly negative", rgb))
    result = world_projection.project_and_store(empty_scene, 3)
    assert result.warnings == []
    assert result.info == ["1 HDRI value was negative and treated as black"]
    assert empty_scene.prt_world.message == ""


def test_large_image_memory_is_bounded(bpy_module, empty_scene):
    """8192x4096 RGBA float: the reduction reads ROW_BLOCK rows at a time, so the numpy peak is
    the one float32 read buffer (512 MiB, which foreach_get needs) plus a few MiB."""
    from prt_addon.blender.world import projection as world_projection

    world = new_world(bpy_module, empty_scene)
    image = bpy_module.data.images.new("big", 8192, 4096, float_buffer=True)
    image.generated_color = (0.5, 1.0, 2.0, 1.0)  # a display colour: Blender linearises it
    twin = bpy_module.data.images.new("twin", 2, 1, float_buffer=True)
    twin.generated_color = image.generated_color
    linear = np.array(twin.pixels[:3])
    assert np.abs(linear - [0.5, 1.0, 2.0]).max() > 0.1
    use_image(world, image)
    buffer_bytes = 8192 * 4096 * 4 * 4
    tracemalloc.start()
    try:
        result = world_projection.project(empty_scene, 8)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < buffer_bytes + 64 * 2**20, peak / 2**20
    assert result.source_size == (8192, 4096)
    assert result.projected_size == (512, 256)
    np.testing.assert_allclose(result.coeffs[0], SQRT_4PI * linear, rtol=1e-6)
    np.testing.assert_allclose(result.coeffs[1:], 0.0, atol=1e-5)
    bpy_module.data.images.remove(image)


def test_reduction_keeps_the_coefficients(bpy_module):
    """Reducing a 1024x512 HDRI to the 256 rows order 16 needs changes no coefficient by more
    than 0.5 % of the coefficient norm (measured 0.1 % on forest; sunny maps up to 0.45 %)."""
    from helpers.worlds import bundled_hdri_path

    image = bpy_module.data.images.load(bundled_hdri_path("forest"))
    w, h = image.size
    buf = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(buf)
    pixels = buf.reshape(h, w, 4)
    full, _ = projection.project_equirect(pixels, 16)
    reduced, _, _ = resample.reduce_equirect(pixels, *resample.target_size(h, w, 16))
    small, _ = projection.project_equirect(reduced, 16)
    assert reduced.shape == (256, 512, 3)
    assert np.linalg.norm(small - full) < 5e-3 * np.linalg.norm(full)
    np.testing.assert_allclose(small[0], full[0], rtol=1e-12)  # the flux is preserved exactly
    bpy_module.data.images.remove(image)


def test_no_world_or_no_light_is_a_clear_error(bpy_module, empty_scene):
    from prt_addon import api

    with pytest.raises(ValueError, match="has no World"):
        api.project_world(empty_scene, 3)
    with pytest.raises(RuntimeError, match="has no World"):
        bpy_module.ops.prt.project_world()
    world = new_world(bpy_module, empty_scene, color=(0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="emits no light"):
        api.project_world(empty_scene, 3)
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (1, 1, 1, 1)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    with pytest.raises(ValueError, match="emits no light"):
        api.project_world(empty_scene, 3)
    world.node_tree.links.clear()
    with pytest.raises(ValueError, match="Nothing is connected"):
        api.project_world(empty_scene, 3)
    assert empty_scene.prt_world.stored_order == 0
    assert "prt_world_sh" not in empty_scene


def test_failed_projection_leaves_stored_lighting_untouched(bpy_module, empty_scene, tmp_path):
    from prt_addon import api

    world = new_world(bpy_module, empty_scene, color=(0.5, 0.5, 0.5))
    api.project_world(empty_scene, 4)
    stored = list(empty_scene["prt_world_sh"])
    token = empty_scene.prt_world.token

    image = float_image(bpy_module, "gone", np.ones((4, 8, 3)))
    image.filepath_raw = str(tmp_path / "gone.exr")
    image.file_format = "OPEN_EXR"
    image.save()
    image.source = "FILE"
    os.remove(image.filepath_raw)
    image.reload()
    env = use_image(world, image)
    with pytest.raises(RuntimeError, match="not found"):
        bpy_module.ops.prt.project_world(order=6)
    env.image = None
    with pytest.raises(RuntimeError, match="has no image"):
        bpy_module.ops.prt.project_world(order=6)
    with pytest.raises(ValueError, match="order"):
        api.project_world(empty_scene, 0)
    assert list(empty_scene["prt_world_sh"]) == stored
    assert empty_scene.prt_world.token == token
    assert empty_scene.prt_world.stored_order == 4


def test_projection_is_saved_with_the_blend_file(bpy_module, empty_scene, tmp_path):
    from prt_addon import api
    from prt_addon.blender.world import projection as world_projection

    c = known_coeffs(4)
    world = new_world(bpy_module, empty_scene)
    env = use_image(world, float_image(bpy_module, "img", image_of(c, 32, 64)))
    env.image.pack()
    add_mapping(world, env, euler=(0.1, 0.2, 0.3))
    result = bpy_module.ops.prt.project_world(order=4)
    assert result == {"FINISHED"}
    expected = api.world_lighting(empty_scene)
    path = str(tmp_path / "saved.blend")
    bpy_module.ops.wm.save_as_mainfile(filepath=path)
    bpy_module.ops.wm.read_factory_settings(use_empty=True)
    bpy_module.ops.wm.open_mainfile(filepath=path)
    scene = bpy_module.context.scene
    settings = scene.prt_world
    assert settings.stored_order == 4
    assert settings.source_kind == "IMAGE"
    assert settings.image_name == "img"
    assert tuple(settings.image_size) == (64, 32)
    assert settings.seconds > 0.0
    assert 0.0 <= settings.truncation < 1.0
    assert len(scene[world_projection.SH_KEY]) == 16 * 3
    assert len(scene[world_projection.SH_WORLD_KEY]) == 16 * 3
    np.testing.assert_allclose(world_projection.current_world_coeffs(scene), expected, atol=1e-12)
