"""Roughness and Metallic from a metallic-roughness image, drawn per pixel by render_view: each quadrant as the constant material of its values."""

import numpy as np
import pytest
from helpers import spec_map_scenes as maps
from helpers.display_scenes import add_camera
from helpers.worlds import bundled_hdri_path, new_world, use_image


@pytest.fixture
def sphere(bpy_module, empty_scene, gpu_ready):
    from prt_addon.blender.world import projection

    bpy = bpy_module
    scene = empty_scene
    scene.prt_display.specular = True
    use_image(new_world(bpy, scene), bpy.data.images.load(bundled_hdri_path("forest"), check_existing=True))
    add_camera(bpy, scene, size=128)
    scene.view_settings.view_transform = "Standard"
    projection.project_and_store(scene, 8)
    obj = maps.uv_sphere(bpy, 8)
    obj.rotation_euler = (0.0, 0.0, np.radians(90.0))  # u = 0.5 (the halves' edge) faces the camera
    bpy.context.view_layer.update()
    return scene, obj


def _use(obj, material):
    obj.data.materials.clear()
    obj.data.materials.append(material)


def _quadrant_pixels(bpy, scene, obj):
    """The sphere's pixels per quadrant of its UV square: drawn diffuse with an image of one colour
    a quadrant (maps.ID_COLOURS), Specular left off."""
    import prt_addon.api as api

    ids = maps.quadrant_image(bpy, "ids", maps.ID_COLOURS, "sRGB")
    _use(obj, maps.id_material(bpy, ids))
    scene.prt_display.specular = False
    return maps.quadrant_masks(api.render_view(scene))


def test_the_map_draws_each_quadrant_as_its_constants(bpy_module, sphere):
    """A sphere whose Roughness (G) and Metallic (B) come from a four-quadrant image, glossy and
    rough, dielectric and metal: every pixel of a quadrant (less 3 at its edges) is the pixel of
    the sphere drawn with that quadrant's constants, within 1 % of its mean (0.05 % on average); the constant draw of
    the node's own (unused) 0.5 / 0.5 is far off."""
    import prt_addon.api as api

    bpy = bpy_module
    scene, obj = sphere
    masks = _quadrant_pixels(bpy, scene, obj)
    scene.prt_display.specular = True
    material, _tex = maps.orm_material(bpy, maps.orm_image(bpy))
    _use(obj, material)
    drawn = api.render_view(scene)[..., :3]
    unused_constants = drawn.copy()
    for q, (roughness, metallic) in maps.QUADRANTS.items():
        mask = masks[q]
        assert mask.sum() > 200, {k: int(m.sum()) for k, m in masks.items()}
        constant, _bsdf = maps.principled(bpy, f"c{q}", roughness=roughness, metallic=metallic)
        _use(obj, constant)
        expected = api.render_view(scene)[..., :3]
        error = np.abs(drawn[mask] - expected[mask]).max() / expected[mask].mean()
        mean_error = np.abs(drawn[mask] - expected[mask]).mean() / expected[mask].mean()
        # (measured: at most 0.5 %, 0.013 % on average, on the glossy metal: the map's 0.2 is
        # 0.19995 in the half-float texture, and its sharp reflection shows it)
        assert error < 0.01 and mean_error < 0.0005, (q, error, mean_error)
        _use(obj, maps.principled(bpy, "half", roughness=0.5, metallic=0.5)[0])
        unused_constants = api.render_view(scene)[..., :3]
        off = np.abs(unused_constants[mask] - expected[mask]).mean() / expected[mask].mean()
        assert off > 0.05, (q, off)
        _use(obj, material)


def test_a_specular_level_map_draws_each_half_as_its_constant(bpy_module, sphere):
    """Specular IOR Level from an image's Color (its luminance: grey 0 and 1 by halves of u) on a
    glossy dielectric: each half as the sphere drawn with that constant level (the dielectric F0 per
    pixel), within 1 % of its mean; the two levels differ by more than 3 % there."""
    import prt_addon.api as api

    bpy = bpy_module
    scene, obj = sphere
    masks = _quadrant_pixels(bpy, scene, obj)
    scene.prt_display.specular = True
    levels = {q: (0.0 if q[0] == 0 else 1.0) for q in maps.QUADRANTS}
    image = maps.quadrant_image(bpy, "levels", {q: (x, x, x) for q, x in levels.items()})
    material, bsdf = maps.principled(bpy, "level", roughness=0.2, metallic=0.0)
    tex = material.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    material.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Specular IOR Level"])
    _use(obj, material)
    drawn = api.render_view(scene)[..., :3]
    constants = {}
    for level in (0.0, 1.0):
        constant, constant_bsdf = maps.principled(bpy, f"l{level}", roughness=0.2, metallic=0.0)
        constant_bsdf.inputs["Specular IOR Level"].default_value = level
        _use(obj, constant)
        constants[level] = api.render_view(scene)[..., :3]
    for q, level in levels.items():
        mask = masks[q]
        expected, other = constants[level][mask], constants[1.0 - level][mask]
        error = np.abs(drawn[mask] - expected).max() / expected.mean()
        apart = np.abs(other - expected).mean() / expected.mean()
        assert error < 0.01 and apart > 0.03, (q, error, apart)  # (measured: 0 and 4.9-7.1 %)


def test_fallbacks_draw_the_constants(bpy_module, sphere, tmp_path):
    """A roughness image whose file is missing draws the socket's constant, pixel for pixel as the
    unlinked material; a float image of roughness 3 and metallic -1 draws as roughness 1 and
    metallic 0 (clamped), and the panel says so once it was read."""
    import prt_addon.api as api
    from prt_addon.blender.display.material_maps import notes

    bpy = bpy_module
    scene, obj = sphere
    plain, _bsdf = maps.principled(bpy, "plain", roughness=0.5, metallic=0.5)
    _use(obj, plain)
    expected = api.render_view(scene)
    gone = bpy.data.images.new("gone", 4, 4)
    gone.source = "FILE"
    gone.filepath = str(tmp_path / "gone.png")
    gone.reload()
    missing, _tex = maps.orm_material(bpy, gone)
    _use(obj, missing)
    assert np.array_equal(api.render_view(scene), expected)
    assert any("'gone' has no pixels" in note for note in notes(obj))
    hdr = bpy.data.images.new("hdr", 4, 4, float_buffer=True)
    hdr.pixels.foreach_set(np.tile(np.array([1.0, 3.0, -1.0, 1.0], np.float32), 16))
    _use(obj, maps.orm_material(bpy, hdr, name="hdr")[0])
    clamped = api.render_view(scene)
    assert "image 'hdr': values outside 0 to 1 clamped" in notes(obj)
    _use(obj, maps.principled(bpy, "ends", roughness=1.0, metallic=0.0)[0])
    ends = api.render_view(scene)
    covered = ends[..., 3] > 0.99
    assert np.abs(clamped - ends)[covered].max() < 1e-3 * ends[covered].max()


def test_an_ior_map_draws_each_half_as_its_constant(bpy_module, sphere):
    """IOR from a float image's Color (1.2 and 2.0 by halves of u) on a glossy dielectric: each half
    as the sphere drawn with that constant IOR (the dielectric F0 per pixel), within 1 % of its mean;
    the two IORs differ by more than 3 % there. An image of IOR 0.5 draws as IOR 1 (clamped: no
    dielectric reflection, the constant level 0's pixels) and the panel says so. Drawn again from
    the same view (the occlusion from its pass's texture) it is the same image."""
    import prt_addon.api as api
    from prt_addon.blender.display.material_maps import notes

    bpy = bpy_module
    scene, obj = sphere
    masks = _quadrant_pixels(bpy, scene, obj)
    scene.prt_display.specular = True
    iors = {q: (1.2 if q[0] == 0 else 2.0) for q in maps.QUADRANTS}
    _use(obj, maps.socket_material(bpy, "ior", maps.halves_image(bpy, "iors", 1.2, 2.0), "IOR")[0])
    drawn = api.render_view(scene)[..., :3]
    # The same view again reads the full-transfer occlusion from its pass's texture beside the IOR
    # image (0.56 off when the two shared a sampler slot).
    assert np.abs(api.render_view(scene)[..., :3] - drawn).max() < 1e-5
    constants = {}
    for ior in (1.2, 2.0):
        constant, constant_bsdf = maps.principled(bpy, f"i{ior}", roughness=0.2, metallic=0.0)
        constant_bsdf.inputs["IOR"].default_value = ior
        _use(obj, constant)
        constants[ior] = api.render_view(scene)[..., :3]
    for q, ior in iors.items():
        mask = masks[q]
        expected, other = constants[ior][mask], constants[2.0 if ior == 1.2 else 1.2][mask]
        error = np.abs(drawn[mask] - expected).max() / expected.mean()
        mean_error = np.abs(drawn[mask] - expected).mean() / expected.mean()
        apart = np.abs(other - expected).mean() / expected.mean()
        print(
            f"{q} IOR {ior}: {100 * error:.3f} % at most, {100 * mean_error:.4f} % on average; apart {100 * apart:.1f} %"
        )
        assert error < 0.01 and mean_error < 0.0005 and apart > 0.03, (q, error, apart)
    _use(obj, maps.socket_material(bpy, "below", maps.halves_image(bpy, "below", 0.5, 0.5), "IOR")[0])
    below = api.render_view(scene)
    assert "image 'below': values below 1 clamped" in notes(obj)
    no_reflection, no_bsdf = maps.principled(bpy, "level0", roughness=0.2, metallic=0.0)
    no_bsdf.inputs["Specular IOR Level"].default_value = 0.0
    _use(obj, no_reflection)
    expected = api.render_view(scene)
    covered = expected[..., 3] > 0.99
    assert np.abs(below - expected)[covered].max() < 1e-3 * expected[covered].max()
