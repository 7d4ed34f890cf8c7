"""Interreflected bakes in Blender: an open room against Cycles, storage, bad input, cancel."""

import warnings

import numpy as np
import pytest

from conftest import bundled_hdri_path
from prt_addon import api
from prt_addon.core import raytrace

pytestmark = pytest.mark.skipif(not raytrace.EMBREE_AVAILABLE, reason="embreex not available")


def diffuse_material(bpy, name, rgb):
    m = bpy.data.materials.new(name)
    with warnings.catch_warnings():  # (use_nodes is deprecated in Blender 5 and still needed in 4.2)
        warnings.simplefilter("ignore", DeprecationWarning)
        m.use_nodes = True
    nodes = m.node_tree.nodes
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (*rgb, 1.0)
    m.node_tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
    return m


def grid(bpy, name, location, rotation, material, cuts=12):
    bpy.ops.mesh.primitive_grid_add(
        x_subdivisions=cuts, y_subdivisions=cuts, size=4, location=location, rotation=rotation
    )
    obj = bpy.context.active_object
    obj.name = name
    obj.data.materials.append(material)
    return obj


def open_room(bpy, scene, hdri=None, red=(0.8, 0.1, 0.1)):
    """A 4 x 4 floor with a red wall (x = -2), a white wall (x = +2) and a white back wall, open
    at the top and the front, with Suzanne inside; a uniform white world or an HDRI."""
    world = bpy.data.worlds.new("room world")
    scene.world = world
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    if hdri is None:
        background.inputs[0].default_value = (1.0, 1.0, 1.0, 1.0)
    else:
        env = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
        env.image = bpy.data.images.load(bundled_hdri_path(hdri))
        world.node_tree.links.new(env.outputs[0], background.inputs[0])
    white = diffuse_material(bpy, "white", (0.8, 0.8, 0.8))
    objs = [
        grid(bpy, "floor", (0, 0, 0), (0, 0, 0), white),
        grid(bpy, "wall_red", (-2, 0, 2), (0, np.pi / 2, 0), diffuse_material(bpy, "red", red)),
        grid(bpy, "wall_white", (2, 0, 2), (0, -np.pi / 2, 0), white),
        grid(bpy, "wall_back", (0, 2, 2), (np.pi / 2, 0, 0), white),
    ]
    bpy.ops.mesh.primitive_monkey_add(location=(0, 0, 0.7), size=1.0)
    suzanne = bpy.context.active_object
    suzanne.name = "Suzanne"
    suzanne.modifiers.new("subdivision", "SUBSURF").levels = 1
    bpy.ops.object.shade_smooth()
    bpy.ops.object.modifier_apply(modifier="subdivision")
    suzanne.data.materials.append(white)
    return objs + [suzanne]


def test_bounces_zero_is_the_direct_bake_and_storage_reads_both(bpy_module, empty_scene):
    from prt_addon.blender import storage

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
        assert b.shape == (len(o.data.vertices), 3, 9) and np.all(b[:, :, 0] >= 0) and b[:, :, 0].max() > 0
        assert api.bake_status(o) == "fresh"
    # Removing one bounce attribute makes the bake stale, not silently direct-only.
    floor = objs[0].data
    floor.attributes.remove(floor.attributes[f"prt_t{3 * 3 - 1:02d}"])
    assert api.bake_status(objs[0]) == "stale"


def test_grey_albedos_store_one_bounce_channel(bpy_module, empty_scene):
    from prt_addon.blender import storage

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
    from prt_addon.core.transfer import Cancelled

    objs = open_room(bpy_module, empty_scene)
    job = BakeJob(objs, BakeSettings(order=2, samples=32, bounces=3))
    texts = []
    with pytest.raises(Cancelled):
        for fraction, text in job.steps():
            texts.append((fraction, text))
            if text.startswith("Bouncing light: pass 1"):
                job.cancel()
        job.finish()
    assert any(t.startswith("Bouncing light") for _f, t in texts)
    fractions = [f for f, _t in texts]
    assert fractions == sorted(fractions) and fractions[-1] < 1.0
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


@pytest.mark.gpu
@pytest.mark.parametrize("order, hdri", [(2, None), (4, "courtyard")])
def test_viewport_draws_the_bounced_transfer_as_shade_computes_it(bpy_module, empty_scene, order, hdri):
    """Order 2 in colour fits the vertex attributes, order 4 in colour (16 vec4s) uses the
    transfer texture; under courtyard.exr the split lights' SH lights the bounced part."""
    import math

    from prt_addon.blender.display import offscreen

    assert offscreen.ensure_gpu()
    bpy = bpy_module
    objs = open_room(bpy, empty_scene, hdri=hdri)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    empty_scene.collection.objects.link(cam)
    cam.location, cam.rotation_euler = (0.0, -7.0, 5.0), (math.radians(55), 0.0, 0.0)
    empty_scene.camera = cam
    empty_scene.prt_display.albedo_source = "WHITE"
    api.project_world(empty_scene, order)
    api.bake(objs, order=order, samples=64, bounces=2)
    size = 256
    image = api.render_view(empty_scene, size, size)
    floor = objs[0]
    expected = api.shade(floor, empty_scene)
    p = np.array([floor.matrix_world @ v.co for v in floor.data.vertices])
    depsgraph = bpy.context.evaluated_depsgraph_get()
    proj = np.array(cam.calc_matrix_camera(depsgraph, x=size, y=size)) @ np.array(cam.matrix_world.inverted())
    clip = np.c_[p, np.ones(len(p))] @ proj.T
    ndc = clip[:, :2] / clip[:, 3:4]
    cols = np.floor((ndc[:, 0] + 1) * 0.5 * size).astype(int)
    rows = np.floor((1 - ndc[:, 1]) * 0.5 * size).astype(int)
    inside = (cols >= 1) & (cols < size - 1) & (rows >= 1) & (rows < size - 1) & (np.abs(p[:, 0]) < 1.8)
    inside &= (p[:, 1] > -1.8) & (p[:, 1] < 1.8) & (np.hypot(p[:, 0], p[:, 1]) > 1.2)  # not behind Suzanne
    got = image[rows[inside], cols[inside], :3]
    want = expected[inside]
    err = np.abs(got - want) / (np.abs(want) + 0.05)
    assert inside.sum() > 40
    # Under courtyard the split lights are four patches of 4 to 23 degrees (45 % of the power):
    # their shadows come from maps, where api.shade traces rays (docs/display.md, "Sun shadows"),
    # measured 1.6-2.0 % (api.shade itself is 0.5 % from a 64-ray-per-sample trace; one filtered
    # map per light was 6-7 %). Without split lights (order 2, uniform world) 0.18 %.
    assert np.median(err) < (0.025 if hdri else 0.01), np.median(err)


def test_export_carries_the_bounced_transfer(bpy_module, empty_scene, tmp_path):
    """Re-imported by Blender's glTF importer, the bounced attributes after the direct ones are
    the stored bounced transfer per channel (in glTF's frame), as docs/export.md specifies."""
    from test_export import _assert_rows_match, _from_gltf, _stored_rows

    from prt_addon.blender import storage
    from prt_addon.blender.export import gltf as export_gltf

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
    assert extras["bounce_channels"] == 3 and extras["per_channel"] and extras["bounces"] == 1
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
    """A wall coloured by an image bounces its mean colour; an albedo above 1 is clamped to 1."""
    from prt_addon.blender import storage

    bpy = bpy_module
    objs = open_room(bpy, empty_scene)
    api.project_world(empty_scene, 2)
    red = objs[1].data.materials[0]
    image = bpy.data.images.new("tex", 2, 2, float_buffer=True)
    pixels = np.array([[0.9, 0.1, 0.1, 1], [0.5, 0.3, 0.1, 1], [0.7, 0.2, 0.0, 1], [0.1, 0.2, 0.4, 1]], np.float32)
    image.pixels.foreach_set(pixels.ravel())
    texture = red.node_tree.nodes.new("ShaderNodeTexImage")
    texture.image = image
    bsdf = red.node_tree.nodes["Diffuse BSDF"]
    red.node_tree.links.new(texture.outputs["Color"], bsdf.inputs["Color"])
    report = api.bake(objs, order=2, samples=64, bounces=1)
    assert any("mean colour of its image 'tex'" in note for note in report.albedo_notes)
    textured = storage.read_bounce(objs[0].data).copy()
    red.node_tree.links.remove(bsdf.inputs["Color"].links[0])
    bsdf.inputs["Color"].default_value = (*pixels[:, :3].mean(axis=0), 1.0)
    api.bake(objs, order=2, samples=64, bounces=1)
    np.testing.assert_allclose(textured, storage.read_bounce(objs[0].data), rtol=1e-5, atol=1e-7)
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
    from prt_addon.blender import storage

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
    """Order 11 in colour: 31 x 4 = 124 attributes (prt_t00 .. prt_t123); baking again without
    bounces leaves the 31 direct ones only."""
    from prt_addon.blender import storage

    objs = open_room(bpy_module, empty_scene)
    api.project_world(empty_scene, 2)
    api.bake(objs, order=11, samples=16, bounces=1)
    mesh = objs[0].data
    assert len(storage.transfer_attribute_names(mesh)) == 124 and api.bake_status(objs[0]) == "fresh"
    assert storage.read_bounce(mesh).shape[1:] == (3, 121)
    snap = storage.snapshot(mesh)
    assert len(snap["attrs"]) == 124
    api.bake(objs, order=11, samples=16)
    assert len(storage.transfer_attribute_names(mesh)) == 31
    assert mesh.attributes.get("prt_t100") is None


def test_an_emission_shader_reflects_nothing(bpy_module, empty_scene):
    """Emission is not light for the bake, and an Emission-only surface has no diffuse BSDF: as
    in Cycles it reflects nothing, so the red wall's tint on the floor disappears."""
    from prt_addon.blender import storage

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
    from prt_addon.blender import storage

    objs = open_room(bpy_module, empty_scene)
    api.project_world(empty_scene, 2)
    results = {}
    for backend in ("EMBREE", "BVHTREE"):
        api.bake(objs, order=2, samples=8, bounces=2, backend=backend)
        results[backend] = storage.read_bounce(objs[0].data).copy()
    np.testing.assert_allclose(results["BVHTREE"], results["EMBREE"], rtol=1e-2, atol=1e-4)
