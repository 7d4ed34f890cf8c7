"""The Mapping node read live, Blender's thread setting, and stale state: format version, caches,
limits shared by the UI and the API."""

import math
import os

import numpy as np
import pytest
from helpers.worlds import add_mapping, float_image, image_of, known_coeffs, new_world, use_image


def _image_world(bpy, scene, order=5):
    c = known_coeffs(order)
    world = new_world(bpy, scene)
    env = use_image(world, float_image(bpy, "img", image_of(c, 64, 128)))
    return world, env


def _fresh_projection(scene, order):
    """What a new Project World gives for the node tree as it is now (checked against Cycles in
    test_world_cycles): the reference the live rotation must equal."""
    from prt_addon import api

    lit = api.world_lighting(scene)
    fresh = api.project_world(scene, order)
    return lit, fresh


def test_mapping_node_added_by_hand_after_projecting_turns_the_lighting(bpy_module, empty_scene):
    from prt_addon import api

    world, env = _image_world(bpy_module, empty_scene)
    unrotated = api.project_world(empty_scene, 5)
    mapping = add_mapping(world, env, euler=(0.0, 0.0, math.pi / 2))  # by hand, not our sidebar
    lit, fresh = _fresh_projection(empty_scene, 5)
    np.testing.assert_allclose(lit, fresh, atol=1e-10)
    assert np.abs(lit - unrotated).max() > 0.1

    mapping.mute = True  # Cycles then shows the world unrotated
    lit, fresh = _fresh_projection(empty_scene, 5)
    np.testing.assert_allclose(lit, unrotated, atol=1e-10)
    np.testing.assert_allclose(fresh, unrotated, atol=1e-10)


def test_mapping_behind_a_reroute_relinked_or_removed(bpy_module, empty_scene):
    from prt_addon import api

    world, env = _image_world(bpy_module, empty_scene)
    tree = world.node_tree
    unrotated = api.project_world(empty_scene, 5)
    mapping = add_mapping(world, env, euler=(0.2, -0.3, 1.1))
    reroute = tree.nodes.new("NodeReroute")
    tree.links.new(mapping.outputs["Vector"], reroute.inputs[0])
    tree.links.new(reroute.outputs[0], env.inputs["Vector"])
    lit, fresh = _fresh_projection(empty_scene, 5)
    np.testing.assert_allclose(lit, fresh, atol=1e-10)
    assert np.abs(lit - unrotated).max() > 0.1

    tree.links.remove(env.inputs["Vector"].links[0])  # unlinked: Generated, no rotation
    np.testing.assert_allclose(api.world_lighting(empty_scene), unrotated, atol=1e-10)

    tree.links.new(mapping.outputs["Vector"], env.inputs["Vector"])  # relinked directly
    lit, fresh = _fresh_projection(empty_scene, 5)
    np.testing.assert_allclose(lit, fresh, atol=1e-10)

    tree.nodes.remove(mapping)
    np.testing.assert_allclose(api.world_lighting(empty_scene), unrotated, atol=1e-10)


def test_display_and_rotation_control_follow_the_same_node(bpy_module, empty_scene):
    """The display's light (with or without a test override) and the sidebar control resolve the
    Mapping node through the reroute like the projection does."""
    from prt_addon import api
    from prt_addon.blender.scene import lighting
    from prt_addon.blender.world import nodes

    world, env = _image_world(bpy_module, empty_scene)
    api.project_world(empty_scene, 5)
    mapping = add_mapping(world, env, euler=(0.0, 0.0, 0.7))
    reroute = world.node_tree.nodes.new("NodeReroute")
    world.node_tree.links.new(mapping.outputs["Vector"], reroute.inputs[0])
    world.node_tree.links.new(reroute.outputs[0], env.inputs["Vector"])
    assert nodes.find_mapping_node(world) == mapping
    assert nodes.mapping_rotation_euler(world) == pytest.approx((0.0, 0.0, 0.7))
    np.testing.assert_allclose(lighting.world_light(empty_scene), api.world_lighting(empty_scene))
    mapping.mute = True
    assert nodes.find_mapping_node(world) is None


def test_bake_follows_blenders_thread_setting(bpy_module, empty_scene):
    from prt_addon.blender.bake import job as bake_job, settings as bake_settings

    bpy = bpy_module
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=1)
    sphere = bpy.context.object
    render = empty_scene.render
    render.threads_mode = "FIXED"
    render.threads = 3
    job = bake_job.BakeJob([sphere], bake_settings.BakeSettings(order=2, samples=16))
    try:
        assert job.settings.threads == 3
        assert job._pool._max_workers == 3
    finally:
        job.close()
    render.threads_mode = "AUTO"
    job = bake_job.BakeJob([sphere], bake_settings.BakeSettings(order=2, samples=16))
    try:
        assert job.settings.threads == os.cpu_count()
    finally:
        job.close()
    job = bake_job.BakeJob([sphere], bake_settings.BakeSettings(order=2, samples=16, threads=1))
    try:
        assert job.settings.threads == 1  # an explicit count wins
    finally:
        job.close()
    with pytest.raises(ValueError, match="threads must be"):
        bake_job.BakeJob([sphere], bake_settings.BakeSettings(order=2, samples=16, threads=0))


def test_a_record_from_a_newer_format_is_not_misread(bpy_module, empty_scene):
    from prt_addon import api
    from prt_addon.blender.scene import storage

    bpy = bpy_module
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=1)
    sphere = bpy.context.object
    api.bake([sphere], order=2, samples=16, shadows=False)
    assert api.bake_status(sphere) == "fresh"
    sphere.data["prt_bake"]["version"] = storage.FORMAT_VERSION + 1
    state, reason = api.bake_status(sphere, reason=True)
    assert state == "stale"
    assert "newer version" in reason
    assert "bake again" in reason
    assert storage.usable_bake(sphere.data) == (None, storage.read_bake_record(sphere.data)[1])
    assert storage.read_transfer(sphere.data) is None


def test_fingerprint_cache_does_not_survive_a_file_load(bpy_module, empty_scene, tmp_path):
    from prt_addon.blender.scene import storage

    bpy = bpy_module
    storage._fingerprint_cache[(1, 2, 3, 4, 200_000)] = "stale"
    path = str(tmp_path / "a.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    assert storage._fingerprint_cache == {}


def test_panel_and_api_share_the_samples_minimum(bpy_module, empty_scene):
    from prt_addon.blender.bake import settings as bake_settings

    prop = empty_scene.prt_bake.bl_rna.properties["samples"]
    assert prop.hard_min == bake_settings.MIN_SAMPLES
    bake_settings.BakeSettings(samples=bake_settings.MIN_SAMPLES).validate()
    with pytest.raises(ValueError, match=rf"samples must be an integer >= {bake_settings.MIN_SAMPLES}, got 1"):
        bake_settings.BakeSettings(samples=bake_settings.MIN_SAMPLES - 1).validate()


def test_operator_report_line_comes_from_the_report_fields(bpy_module):
    from prt_addon.blender.bake import reports, settings

    report = settings.BakeReport(
        ok=True,
        objects=["a", "b"],
        backend="EMBREE",
        seconds=1.25,
        rays_traced=1_234_567,
        error_estimate_relative=0.031,
        note="a note",
        skipped=[("c", "is a camera")],
    )
    said = []

    class Op:
        def report(self, kind, message):
            said.append((set(kind), message))

    reports._report_to_operator(Op(), report)
    assert said[0] == ({"INFO"}, "PRT: Baked 2 object(s) in 1.25 s (EMBREE), 1,234,567 rays, error estimate 3.10 %")
    assert said[1] == ({"WARNING"}, "PRT: a note")
    assert said[2] == ({"WARNING"}, "PRT: skipped 'c': is a camera")
