"""Interreflected bakes in Blender: an open room against Cycles, storage, bad input, cancel."""

import numpy as np
import pytest
from helpers.rooms import open_room

from prt_addon import api
from prt_addon.core.trace import raytrace

pytestmark = pytest.mark.skipif(not raytrace.EMBREE_AVAILABLE, reason="embreex not available")


def test_bounces_zero_is_the_direct_bake_and_storage_reads_both(bpy_module, empty_scene):
    from prt_addon.blender.scene import storage

    objs = open_room(bpy_module, empty_scene)
    api.project_world(empty_scene, 3)
    api.bake(objs, order=3, samples=64)
    plain = {o.name: storage.read_transfer(o.data).copy() for o in objs}
    assert all(storage.read_bounce(o.data) is None for o in objs)
    assert objs[0].data["prt_bake"]["version"] == 1  # readable by versions before bounces
    api.bake(objs, order=3, samples=64, bounces=0)
    for o in objs:
        assert np.array_equal(storage.read_transfer(o.data), plain[o.name])
    api.bake(objs, order=3, samples=64, bounces=2)
    for o in objs:
        np.testing.assert_array_equal(storage.read_transfer(o.data), plain[o.name])  # direct unchanged
        b = storage.read_bounce(o.data)
        assert b.shape == (len(o.data.vertices), 3, 9)
        assert np.all(b[:, :, 0] >= 0)
        assert b[:, :, 0].max() > 0
        assert api.bake_status(o) == "fresh"
    # Removing one bounce attribute makes the bake stale, not silently direct-only.
    floor = objs[0].data
    floor.attributes.remove(floor.attributes[f"prt_t{3 * 3 - 1:02d}"])
    assert api.bake_status(objs[0]) == "stale"


def test_grey_albedos_store_one_bounce_channel(bpy_module, empty_scene):
    from prt_addon.blender.scene import storage

    objs = open_room(bpy_module, empty_scene, red=(0.5, 0.5, 0.5))
    api.project_world(empty_scene, 2)
    report = api.bake(objs, order=2, samples=64, bounces=1)
    assert report.bounce_channels == 1
    assert storage.read_bounce(objs[0].data).shape[1] == 1


@pytest.mark.parametrize("bounces", [-1, 9, 1.5, "2", True])
def test_bad_bounces_are_refused_and_change_nothing(bpy_module, empty_scene, bounces):
    objs = open_room(bpy_module, empty_scene)
    with pytest.raises(ValueError, match="bounces must be an integer from 0 to 8"):
        api.bake(objs, order=2, samples=16, bounces=bounces)
    assert all("prt_bake" not in o.data for o in objs)


def test_bounces_need_scene_shadows(bpy_module, empty_scene):
    objs = open_room(bpy_module, empty_scene)
    with pytest.raises(ValueError, match="bounces need shadows"):
        api.bake(objs, order=2, samples=16, bounces=2, shadows=False)
    with pytest.raises(ValueError, match="Self Shadow Only"):
        api.bake(objs, order=2, samples=16, bounces=2, self_shadow_only=True)


def test_cancel_during_the_bounce_passes_leaves_the_meshes_as_they_were(bpy_module, empty_scene):
    from prt_addon.blender.bake.job import BakeJob
    from prt_addon.blender.bake.settings import BakeSettings
    from prt_addon.core.transfer.quadrature import Cancelled

    objs = open_room(bpy_module, empty_scene)
    job = BakeJob(objs, BakeSettings(order=2, samples=32, bounces=3))
    texts = []

    def run_until_cancelled():
        for fraction, text in job.steps():
            texts.append((fraction, text))
            if text.startswith("Bouncing light: pass 1"):
                job.cancel()
        job.finish()

    with pytest.raises(Cancelled):
        run_until_cancelled()
    assert any(t.startswith("Bouncing light") for _f, t in texts)
    fractions = [f for f, _t in texts]
    assert fractions == sorted(fractions)
    assert fractions[-1] < 1.0
    assert all("prt_bake" not in o.data for o in objs)


def test_unbaked_meshes_bounce_light_too(bpy_module, empty_scene):
    """Only the floor is baked: the walls and Suzanne still reflect light onto it."""
    objs = open_room(bpy_module, empty_scene)
    api.project_world(empty_scene, 2)
    api.bake(objs[0], order=2, samples=128)
    direct = api.shade(objs[0], empty_scene)
    report = api.bake(objs[0], order=2, samples=128, bounces=2)
    assert report.bounce_points == sum(len(o.data.vertices) for o in objs[1:])
    bounced = api.shade(objs[0], empty_scene)
    api.bake(objs, order=2, samples=128, bounces=2)
    all_baked = api.shade(objs[0], empty_scene)
    assert bounced.mean() > 1.2 * direct.mean()
    np.testing.assert_allclose(bounced, all_baked, rtol=1e-4, atol=1e-6)  # the same light either way


def test_export_carries_the_bounced_transfer(bpy_module, empty_scene, tmp_path):
    """Re-imported by Blender's glTF importer, the bounced attributes after the direct ones are
    the stored bounced transfer per channel (in glTF's frame), as docs/export.md specifies."""
    from helpers.gltf import _assert_rows_match, _from_gltf, _stored_rows

    from prt_addon.blender.export import gltf as export_gltf
    from prt_addon.blender.scene import storage

    bpy = bpy_module
    objs = open_room(bpy, empty_scene)
    api.project_world(empty_scene, 2)
    api.bake(objs, order=2, samples=32, bounces=1)
    wall = objs[1]
    pos, direct = _stored_rows(wall)
    bounced = storage.read_bounce(wall.data).astype(np.float64)
    name = wall.name
    # float32: Blender's importer reads a quantised transfer as q / K (docs/export.md, "Quantised transfer").
    path = export_gltf.export_gltf(str(tmp_path / "room.glb"), [wall], transfer="float32")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=path)
    mesh = bpy.data.objects[name].data
    extras = mesh.get("PRT_lighting")
    assert extras["bounce_channels"] == 3
    assert extras["per_channel"]
    assert extras["bounces"] == 1
    assert list(extras["bounce_attributes"]) == ["_PRT_T1", "_PRT_T2", "_PRT_T3"]

    def column(k):
        attr = mesh.attributes[f"_PRT_T{k}"]
        buf = np.empty(len(attr.data) * 4, np.float32)
        attr.data.foreach_get("color" if attr.data_type in ("FLOAT_COLOR", "BYTE_COLOR") else "vector", buf)
        return buf.reshape(-1, 4).astype(np.float64)

    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3).astype(np.float64)
    _assert_rows_match(pos, direct, co, _from_gltf(column(0)))
    for c in range(3):
        _assert_rows_match(pos, bounced[:, c], co, _from_gltf(column(1 + c)))


def test_textured_and_over_bright_albedo(bpy_module, empty_scene):
    """A wall coloured by the red half of a red/blue image bounces red, as the same wall in constant
    red does (the image's mean, purple, would not); an albedo above 1 is clamped to 1."""
    from prt_addon.blender.scene import storage

    bpy = bpy_module
    objs = open_room(bpy, empty_scene)
    api.project_world(empty_scene, 2)
    wall = objs[1].data
    red = wall.materials[0]
    image = bpy.data.images.new("tex", 8, 8, float_buffer=True)
    pixels = np.zeros((8, 8, 4), np.float32)
    pixels[..., 3] = 1.0
    pixels[:, :4, :3] = (0.8, 0.1, 0.1)
    pixels[:, 4:, :3] = (0.1, 0.1, 0.8)
    image.pixels.foreach_set(pixels.ravel())
    uv = np.empty(2 * len(wall.loops), np.float32)
    wall.uv_layers[0].data.foreach_get("uv", uv)
    wall.uv_layers[0].data.foreach_set("uv", 0.1 + 0.25 * uv)  # u in 0.1..0.35: the red half, inside
    texture = red.node_tree.nodes.new("ShaderNodeTexImage")
    texture.image = image
    bsdf = red.node_tree.nodes["Diffuse BSDF"]
    red.node_tree.links.new(texture.outputs["Color"], bsdf.inputs["Color"])
    report = api.bake(objs, order=2, samples=64, bounces=1)
    assert any("'tex': bounced light uses the image at each hit" in note for note in report.albedo_notes)
    assert not any("mean colour" in note for note in report.albedo_notes)
    textured = storage.read_bounce(objs[0].data).copy()
    red.node_tree.links.remove(bsdf.inputs["Color"].links[0])
    bsdf.inputs["Color"].default_value = (0.8, 0.1, 0.1, 1.0)
    api.bake(objs, order=2, samples=64, bounces=1)
    constant = storage.read_bounce(objs[0].data)
    np.testing.assert_allclose(textured, constant, rtol=1e-4, atol=1e-7)
    # The same red from a colour attribute on the wall (its corners' mean per triangle).
    wall.color_attributes.new("Col", "FLOAT_COLOR", "CORNER")
    wall.attributes["Col"].data.foreach_set("color", np.tile([0.8, 0.1, 0.1, 1.0], len(wall.loops)).astype(np.float32))
    node = red.node_tree.nodes.new("ShaderNodeVertexColor")
    node.layer_name = "Col"
    red.node_tree.links.new(node.outputs["Color"], bsdf.inputs["Color"])
    report = api.bake(objs, order=2, samples=64, bounces=1)
    assert any("colour attribute 'Col'" in note for note in report.albedo_notes)
    np.testing.assert_allclose(storage.read_bounce(objs[0].data), constant, rtol=1e-4, atol=1e-7)
    red.node_tree.links.remove(bsdf.inputs["Color"].links[0])
    floor_x = np.array([v.co.x for v in objs[0].data.vertices])
    near = constant[floor_x < -1.2, :, 0].mean(axis=0)  # the floor by the wall: red over blue
    assert near[0] > 1.5 * near[2]
    bsdf.inputs["Color"].default_value = (1.5, 0.2, 0.2, 1.0)
    report = api.bake(objs, order=2, samples=64, bounces=1)
    assert any("clamped" in note for note in report.albedo_notes)
    from prt_addon.blender.bake import reports

    said = []

    class Operator:
        def report(self, kind, message):
            said.append((set(kind), message))

    reports._report_to_operator(Operator(), report)
    assert any(kind == {"WARNING"} and "clamped" in message for kind, message in said)
    bright = storage.read_bounce(objs[0].data).copy()
    bsdf.inputs["Color"].default_value = (1.0, 0.2, 0.2, 1.0)
    api.bake(objs, order=2, samples=64, bounces=1)
    np.testing.assert_array_equal(bright, storage.read_bounce(objs[0].data))


def test_a_mirrored_wall_reflects_like_the_same_wall_unmirrored(bpy_module, empty_scene):
    """Scale -1 reverses a mesh's winding in world space; its faces must still reflect (a plane
    mirrored across its own plane's normal axis is the same surface)."""
    from prt_addon.blender.scene import storage

    objs = open_room(bpy_module, empty_scene)
    api.project_world(empty_scene, 2)
    floor, wall = objs[0], objs[3]  # the back wall, a plane in y = 2 facing -y
    for obj in objs[1:]:
        if obj is not wall:
            obj.hide_viewport = True
    api.bake([floor], order=2, samples=128, bounces=1)
    plain = storage.read_bounce(floor.data).copy()
    assert plain[:, 0, 0].mean() > 0.01
    wall.scale = (-1.0, 1.0, 1.0)  # mirrored across its local x: the same plane, reversed winding
    api.bake([floor], order=2, samples=128, bounces=1)
    mirrored = storage.read_bounce(floor.data)
    # The same surface, but its quads split along the other diagonal in world space and its
    # vertices in another order, so the hits' corners differ: the same light up to sampling
    # (before the fix, a mirrored mesh reflected nothing at all).
    assert mirrored[:, 0, 0].mean() == pytest.approx(plain[:, 0, 0].mean(), rel=0.02)
    assert np.corrcoef(mirrored[:, 0, 0], plain[:, 0, 0])[0, 1] > 0.9


def test_more_than_a_hundred_attributes_are_written_and_cleaned(bpy_module, empty_scene):
    """Order 11 in colour: 31 x 4 = 124 attributes (prt_t00 .. prt_t123), and the open floor's
    back side 31 more (prt_tb00 .. prt_tb30); baking again without bounces leaves the 31 direct
    ones and the back's."""
    from prt_addon.blender.scene import storage

    objs = open_room(bpy_module, empty_scene)
    api.project_world(empty_scene, 2)
    api.bake(objs, order=11, samples=16, bounces=1)
    mesh = objs[0].data
    assert len(storage.transfer_attribute_names(mesh)) == 124 + 31
    assert api.bake_status(objs[0]) == "fresh"
    assert storage.read_bounce(mesh).shape[1:] == (3, 121)
    snap = storage.snapshot(mesh)
    assert len(snap["attrs"]) == 124 + 31
    api.bake(objs, order=11, samples=16)
    assert len(storage.transfer_attribute_names(mesh)) == 31 + 31
    assert mesh.attributes.get("prt_t100") is None


def test_an_emission_shader_reflects_nothing(bpy_module, empty_scene):
    """Emission is not light for the bake, and an Emission-only surface has no diffuse BSDF: as
    in Cycles it reflects nothing, so the red wall's tint on the floor disappears."""
    from prt_addon.blender.scene import storage

    objs = open_room(bpy_module, empty_scene)
    api.project_world(empty_scene, 2)
    floor, red_wall = objs[0], objs[1]
    x = np.array([floor.matrix_world @ v.co for v in floor.data.vertices])[:, 0]

    def tint():
        b = storage.read_bounce(floor.data)[:, :, 0]
        if b.shape[1] == 1:  # every albedo grey (the wall reflects nothing): one channel, no tint
            return 1.0
        near_red, near_white = b[x < -1.2].mean(axis=0), b[x > 1.2].mean(axis=0)
        return (near_red[0] / near_red[1]) / (near_white[0] / near_white[1])

    api.bake(objs, order=2, samples=128, bounces=1)
    assert tint() > 1.3
    tree = red_wall.data.materials[0].node_tree
    emission = tree.nodes.new("ShaderNodeEmission")
    emission.inputs["Color"].default_value = (1.0, 0.0, 0.0, 1.0)
    tree.links.new(emission.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    report = api.bake(objs, order=2, samples=128, bounces=1)
    assert any("Emission shader reflects nothing" in note for note in report.albedo_notes)
    assert tint() < 1.05


def test_the_panel_bounces_are_used_only_with_scene_shadows(bpy_module, empty_scene):
    """The Bounces row is greyed out without scene shadows; the operator then bakes direct light
    (as Blender ignores an inactive setting) instead of refusing."""
    from prt_addon.blender.ops.bake import settings_from

    group = empty_scene.prt_bake
    group.bounces = 3
    assert settings_from(group).validate().bounces == 3
    group.shadows = False
    assert settings_from(group).validate().bounces == 0
    group.shadows, group.self_shadow_only = True, True
    assert settings_from(group).validate().bounces == 0


def test_the_bvh_tree_fallback_bounces_like_embree(bpy_module, empty_scene):
    """Blender's BVH tree (the fallback without embreex) finds the same first hits: its
    barycentrics are solved from ray_cast's hit point, Embree's by Moller-Trumbore."""
    from prt_addon.blender.scene import storage

    objs = open_room(bpy_module, empty_scene)
    api.project_world(empty_scene, 2)
    results = {}
    for backend in ("EMBREE", "BVHTREE"):
        api.bake(objs, order=2, samples=8, bounces=2, backend=backend)
        results[backend] = storage.read_bounce(objs[0].data).copy()
    np.testing.assert_allclose(results["BVHTREE"], results["EMBREE"], rtol=1e-2, atol=1e-4)
