"""Texel bakes through api.bake(target="TEXELS"): values against closed forms, the UV map they use or make, storage and staleness, bad input."""

import numpy as np
import pytest

UNIFORM = np.zeros((9, 3))
UNIFORM[0] = np.sqrt(4.0 * np.pi)  # radiance 1 from every direction: E / pi = 1 on an open surface


def _plane(bpy, uv_scale=1.0, name="Plane"):
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    obj = bpy.context.object
    obj.name = obj.data.name = name
    if uv_scale != 1.0:
        uv = obj.data.uv_layers["UVMap"].uv
        values = np.empty(len(uv) * 2, np.float32)
        uv.foreach_get("vector", values)
        uv.foreach_set("vector", ((values - 0.5) * uv_scale + 0.5).astype(np.float32))
    return obj


def _uniform_light(scene):
    from prt_addon.blender.scene import lighting

    lighting.set_light_override(scene, UNIFORM)


def _state(bpy, obj):
    """What a bake may change: attributes, UV maps and their values, the record, the images."""
    mesh = obj.data
    uvs = {}
    for layer in mesh.uv_layers:
        values = np.empty(len(layer.uv) * 2, np.float32)
        layer.uv.foreach_get("vector", values)
        uvs[layer.name] = values.tobytes()
    record = mesh.get("prt_bake")
    return (
        sorted(a.name for a in mesh.attributes),
        uvs,
        mesh.uv_layers.active_index,
        None if record is None else str(record.to_dict()),
        sorted(i.name for i in bpy.data.images),
    )


def test_an_open_plane_under_a_uniform_sky_is_one_per_texel_gutter_included(bpy_module, empty_scene):
    from prt_addon import api

    bpy = bpy_module
    obj = _plane(bpy, uv_scale=0.5)  # the face covers the middle of the map: a gutter around it
    _uniform_light(empty_scene)
    report = api.bake([obj], order=3, samples=256, target="TEXELS", uv_map="UVMap", resolution=32)
    assert report.ok
    assert 16 * 16 <= report.texels <= 18 * 18  # the face's 16 x 16 texels (and those its edges touch)
    shaded = api.shade(obj)
    assert shaded.shape == (32, 32, 3)
    inside = np.zeros((32, 32), bool)
    inside[6:26, 6:26] = True  # the face (texels 8 to 23) and a gutter of 2 around it
    np.testing.assert_allclose(shaded[inside], 1.0, atol=2e-3)
    assert api.bake_status(obj) == "fresh"


def test_a_texel_bake_stores_a_packed_float_image_and_a_record(bpy_module, empty_scene):
    from prt_addon import api

    bpy = bpy_module
    obj = _plane(bpy)
    _uniform_light(empty_scene)
    api.bake([obj], order=4, samples=64, target="TEXELS", uv_map="UVMap", resolution=16)
    record = obj.data["prt_bake"]
    assert record["domain"] == "TEXEL"
    assert record["resolution"] == 16
    assert record["uv_map"] == "UVMap"
    image = bpy.data.images[record["image"]]
    assert image.name == "PRT Plane"
    assert image.packed_file is not None
    assert image.use_fake_user
    assert image.is_float
    assert image.colorspace_settings.is_data
    assert tuple(image.size) == (32, 32)  # order 4: 16 coefficients, 4 tiles of 16 x 16
    assert not [a.name for a in obj.data.attributes if a.name.startswith("prt_t")]


def test_without_a_lightmap_uv_map_the_bake_makes_one_and_leaves_the_others(bpy_module, empty_scene):
    from prt_addon import api

    bpy = bpy_module
    obj = _plane(bpy)
    _uniform_light(empty_scene)
    before = _state(bpy, obj)
    report = api.bake([obj], order=2, samples=64, target="TEXELS", resolution=16)
    after = _state(bpy, obj)
    assert list(after[1]) == ["UVMap", "PRT Lightmap"]
    assert after[1]["UVMap"] == before[1]["UVMap"]
    assert after[2] == before[2]  # the active UV map stays the user's
    assert obj.data["prt_bake"]["uv_map"] == "PRT Lightmap"
    assert any("made the UV map 'PRT Lightmap'" in line for line in report.report_lines())
    # A second bake finds it by name and makes no other.
    api.bake([obj], order=2, samples=64, target="TEXELS", resolution=16)
    assert [layer.name for layer in obj.data.uv_layers] == ["UVMap", "PRT Lightmap"]


def test_changing_or_removing_the_uv_map_makes_the_bake_stale(bpy_module, empty_scene):
    from prt_addon import api

    bpy = bpy_module
    obj = _plane(bpy)
    _uniform_light(empty_scene)
    api.bake([obj], order=2, samples=64, target="TEXELS", uv_map="UVMap", resolution=16)
    uv = obj.data.uv_layers["UVMap"].uv
    uv[0].vector = (0.3, 0.2)
    state, why = api.bake_status(obj, reason=True)
    assert state == "stale"
    assert "UV map 'UVMap' changed" in why
    with pytest.raises(ValueError, match="UV map 'UVMap' changed"):
        api.shade(obj)
    obj.data.uv_layers.remove(obj.data.uv_layers["UVMap"])
    assert "was removed" in api.bake_status(obj, reason=True)[1]


def test_a_deleted_transfer_image_makes_the_bake_stale(bpy_module, empty_scene):
    from prt_addon import api

    bpy = bpy_module
    obj = _plane(bpy)
    _uniform_light(empty_scene)
    api.bake([obj], order=2, samples=64, target="TEXELS", uv_map="UVMap", resolution=16)
    bpy.data.images.remove(bpy.data.images["PRT Plane"])
    state, why = api.bake_status(obj, reason=True)
    assert state == "stale"
    assert "transfer image 'PRT Plane' is missing" in why


def test_a_vertex_bake_after_a_texel_bake_removes_its_image(bpy_module, empty_scene):
    from prt_addon import api

    bpy = bpy_module
    obj = _plane(bpy)
    _uniform_light(empty_scene)
    api.bake([obj], order=2, samples=64, target="TEXELS", uv_map="UVMap", resolution=16)
    api.bake([obj], order=2, samples=64)
    assert "PRT Plane" not in bpy.data.images
    assert obj.data["prt_bake"]["domain"] == "POINT"
    assert api.shade(obj).shape == (4, 3)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"uv_map": "Nope"}, r"has no UV map 'Nope' \(its UV maps: 'UVMap'\)"),
        ({"resolution": 0}, "resolution must be None"),
        ({"resolution": -4}, "resolution must be None"),
        ({"resolution": 2.5}, "resolution must be None"),
        ({"resolution": 10**6}, "above the largest lightmap"),
    ],
)
def test_bad_texel_settings_are_refused_and_change_nothing(bpy_module, empty_scene, options, message):
    from prt_addon import api

    bpy = bpy_module
    obj = _plane(bpy)
    _uniform_light(empty_scene)
    before = _state(bpy, obj)
    with pytest.raises(ValueError, match=message):
        api.bake([obj], order=2, samples=32, target="TEXELS", **{"uv_map": "UVMap", **options})
    assert _state(bpy, obj) == before


def test_overlapping_uvs_are_refused_with_the_way_out(bpy_module, empty_scene):
    """A mirrored texture layout (both halves of a grid on the same UVs) is no lightmap."""
    from prt_addon import api

    bpy = bpy_module
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=2, y_subdivisions=1, size=2.0)
    obj = bpy.context.object
    uv = obj.data.uv_layers["UVMap"].uv
    values = np.empty(len(uv) * 2, np.float32)
    uv.foreach_get("vector", values)
    values = values.reshape(-1, 2)
    values[:, 0] = np.abs(values[:, 0] - 0.5) * 2.0  # fold the left half onto the right
    uv.foreach_set("vector", values.reshape(-1))
    _uniform_light(empty_scene)
    before = _state(bpy, obj)
    with pytest.raises(ValueError, match=r"overlaps itself .*Leave UV Map empty to make one"):
        api.bake([obj], order=2, samples=32, target="TEXELS", uv_map="UVMap", resolution=16)
    assert _state(bpy, obj) == before


def test_uvs_of_no_area_are_refused(bpy_module, empty_scene):
    from prt_addon import api

    bpy = bpy_module
    obj = _plane(bpy)
    uv = obj.data.uv_layers["UVMap"].uv
    uv.foreach_set("vector", np.full(len(uv) * 2, 0.5, np.float32))
    _uniform_light(empty_scene)
    with pytest.raises(ValueError, match="has no area"):
        api.bake([obj], order=2, samples=32, target="TEXELS", uv_map="UVMap", resolution=16)


def test_a_failed_texel_bake_leaves_no_image_and_no_uv_map(bpy_module, empty_scene):
    from prt_addon import api

    bpy = bpy_module
    obj = _plane(bpy)
    _uniform_light(empty_scene)
    before = _state(bpy, obj)

    def stop(_fraction, _text):
        raise RuntimeError("stopped by the test")

    with pytest.raises(RuntimeError, match="stopped by the test"):
        api.bake([obj], order=2, samples=64, target="TEXELS", resolution=16, progress=stop)
    assert _state(bpy, obj) == before
    assert not [i for i in bpy.data.images if i.name.startswith("PRT ")]


def test_auto_bakes_texels_for_a_coarse_mesh_and_vertices_for_a_dense_one(bpy_module, empty_scene):
    from prt_addon import api

    bpy = bpy_module
    floor = _plane(bpy, name="Floor")
    bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, radius=0.5, location=(0, 0, 1))
    ball = bpy.context.object
    _uniform_light(empty_scene)
    api.bake([floor, ball], order=2, samples=32, target="AUTO", resolution=16)
    assert floor.data["prt_bake"]["domain"] == "TEXEL"
    assert ball.data["prt_bake"]["domain"] in ("POINT", "CORNER")
