"""The transfer bake through the operator and the API: storage, per-vertex or per-corner points, values, scale.

Its fixtures (bake_ops, mesh_io: tests/helpers/fixtures_bake.py) and scene helpers
(tests/helpers/bake_scenes.py) are shared with test_bake_job.py (backends, the modal path,
threads, failure safety) and test_bake_status.py (staleness, refusals).
"""

import json

import numpy as np
import pytest
from helpers.bake_scenes import _monkey_on_ground

from prt_addon.core.sh import analytic, frames


def _scale_scene(bpy, factor):
    for obj in bpy.context.scene.objects:
        obj.location = obj.location * factor
        obj.scale = obj.scale * factor
    bpy.context.view_layer.update()


def test_operator_bakes_selection_and_writes_storage(empty_scene, bpy_module, mesh_io):
    from prt_addon.blender.scene import storage

    bpy = bpy_module
    ground, monkey = _monkey_on_ground(bpy)
    for obj in (ground, monkey):
        obj.select_set(True)
    settings = empty_scene.prt_bake
    settings.order, settings.samples = 3, 64
    assert bpy.ops.prt.bake_transfer() == {"FINISHED"}
    record = monkey.data["prt_bake"]
    assert record["order"] == 3
    assert record["count"] == 3
    assert record["domain"] == "POINT"
    assert record["backend"] in ("EMBREE", "BVHTREE")
    assert record["rays_traced"] > 0
    for k in range(3):
        attr = monkey.data.attributes[f"prt_t{k:02d}"]
        assert attr.data_type == "FLOAT_COLOR"
        assert attr.domain == "POINT"
    values = storage.read_transfer(monkey.data)
    assert values.shape == (len(monkey.data.vertices), 9)
    assert np.isfinite(values).all()
    report = json.loads(settings.last_report)
    assert report["ok"]
    assert report["rays_traced"] > 0
    assert report["error_estimate"] > 0
    assert set(report["objects"]) == {ground.name, monkey.name}
    from prt_addon import api

    assert api.bake_status(monkey) == "fresh"
    assert api.bake_status(ground) == "fresh"
    # Lower order: the extra attributes go; higher again: they come back. (Suzanne is open, so it
    # has a back side too: prt_tbKK, tests/blender/test_back_faces.py.)
    api.bake([monkey], order=2, samples=32)
    assert monkey.data["prt_bake"]["count"] == 1
    assert [a.name for a in monkey.data.attributes if a.name.startswith("prt_t")] == ["prt_t00", "prt_tb00"]
    assert "UNDO" in bpy.types.PRT_OT_bake_transfer.bl_options


def test_flat_shading_bakes_per_corner(empty_scene, bpy_module, mesh_io):
    bpy = bpy_module
    ground, monkey = _monkey_on_ground(bpy, smooth=False)
    from prt_addon import api

    api.bake([monkey, ground], order=2, samples=32)
    assert monkey.data["prt_bake"]["domain"] == "CORNER"
    assert len(monkey.data.attributes["prt_t00"].data) == len(monkey.data.loops)
    # A flat grid has one normal per vertex: stored per vertex.
    assert ground.data["prt_bake"]["domain"] == "POINT"


def test_loose_vertices_do_not_fool_the_per_vertex_shortcut(empty_scene, bpy_module, mesh_io):
    """Two flat triangles folded along an edge (its 2 vertices have 2 normals each) plus 2 loose
    vertices: 6 (vertex, normal) pairs for 6 vertices, but not one normal per vertex. It must bake
    per corner, each corner holding the clamped cosine of its own face's normal."""
    from prt_addon.blender.scene import storage

    bpy = bpy_module
    mesh = bpy.data.meshes.new("fold")
    verts = [(0, 0, 0), (1, 0, 0), (0.5, 1, 0), (0.5, -1, 0.8), (5, 5, 5), (6, 5, 5)]
    mesh.from_pydata(verts, [], [(0, 1, 2), (1, 0, 3)])
    mesh.shade_flat()
    obj = bpy.data.objects.new("fold", mesh)
    empty_scene.collection.objects.link(obj)
    from prt_addon import api

    api.bake([obj], order=2, samples=64, shadows=False)
    assert mesh["prt_bake"]["domain"] == "CORNER"
    values = storage.read_transfer(mesh)
    face_normals = np.array([p.normal for p in mesh.polygons])
    expected = np.array(
        [analytic.clamped_cosine_coeffs(2, face_normals[p.index]) for p in mesh.polygons for _ in p.loop_indices]
    )
    np.testing.assert_allclose(values, expected, atol=2e-2)


def test_unoccluded_vertex_is_clamped_cosine_in_local_frame(empty_scene, bpy_module, mesh_io):
    """A lone convex object: no rays at all, and each vertex stores the clamped cosine of its
    local normal (the local frame undoes the object's rotation and scale)."""
    from prt_addon.blender.scene import mesh_read, storage

    bpy = bpy_module
    bpy.ops.mesh.primitive_uv_sphere_add(segments=12, ring_count=6, rotation=(0.3, 0.5, 0.7), scale=(1, 2, 0.5))
    sphere = bpy.context.object
    sphere.data.shade_smooth()
    from prt_addon import api

    report = api.bake([sphere], order=3, samples=2048)
    assert report.rays_traced == 0
    assert report.backend == "NONE"
    assert report.skipped_unoccludable > 0
    normals = mesh_read.read_vertex_normals(sphere.data).astype(np.float64)
    # Normals in the local frame: world normal (inverse transpose) rotated back by R^-1.
    m = np.array(sphere.matrix_world)[:3, :3]
    world = normals @ np.linalg.inv(m)
    world /= np.linalg.norm(world, axis=1, keepdims=True)
    r, _ = frames.frame_rotation(m)
    local = world @ r
    values = storage.read_transfer(sphere.data)
    expected = np.array([analytic.clamped_cosine_coeffs(3, n) for n in local])
    np.testing.assert_allclose(values, expected, atol=2e-4)


def test_coarse_smooth_mesh_does_not_shadow_itself(empty_scene, bpy_module, mesh_io):
    from prt_addon.blender.scene import storage

    bpy = bpy_module
    bpy.ops.mesh.primitive_uv_sphere_add(segments=8, ring_count=4)
    sphere = bpy.context.object
    sphere.data.shade_smooth()
    from prt_addon import api

    report = api.bake([sphere], order=3, samples=512, self_shadow_only=True, cull=False)
    assert report.rays_traced > 0
    shadowed = storage.read_transfer(sphere.data)
    api.bake([sphere], order=3, samples=512, shadows=False)
    np.testing.assert_array_equal(shadowed, storage.read_transfer(sphere.data))


def _scene_values(bpy, mesh_io, factor):
    from prt_addon.blender.scene import storage

    bpy.ops.wm.read_factory_settings(use_empty=True)
    ground, monkey = _monkey_on_ground(bpy, ground_cuts=6)
    if factor != 1.0:
        _scale_scene(bpy, factor)
    from prt_addon import api

    report = api.bake([monkey, ground], order=3, samples=128, seed=7)
    report.offset = monkey.data["prt_bake"]["offset"]
    return storage.read_transfer(monkey.data), storage.read_transfer(ground.data), report


def test_scene_scale_does_not_change_the_result(empty_scene, bpy_module, mesh_io):
    bpy = bpy_module
    ref_m, ref_g, ref = _scene_values(bpy, mesh_io, 1.0)
    for factor in (1e-3, 1e3):
        m, g, rep = _scene_values(bpy, mesh_io, factor)
        assert rep.rays_traced == ref.rays_traced
        assert rep.offset == pytest.approx(factor * ref.offset, rel=1e-6)  # the offset scales
        for a, b in ((m, ref_m), (g, ref_g)):
            diff = np.abs(a - b)
            # float32 rounding flips a handful of grazing rays at most.
            assert np.mean(diff) < 1e-5 and np.quantile(diff, 0.999) < 2e-2, (factor, diff.max())


def test_lone_convex_object_traces_nothing_and_ground_contact_does(empty_scene, bpy_module):
    bpy = bpy_module
    from prt_addon import api

    bpy.ops.mesh.primitive_cube_add(location=(0, 0, 1))
    cube = bpy.context.object
    report = api.bake([cube], order=2, samples=64)
    assert report.rays_traced == 0
    assert report.backend == "NONE"
    assert report.points == 24  # flat cube: 8 vertices x 3 face normals
    assert report.rays_skipped == 64 * report.points
    assert report.skipped_below_horizon + report.skipped_unoccludable == report.rays_skipped
    assert cube.data["prt_bake"]["backend"] == "NONE"
    bpy.ops.mesh.primitive_plane_add(size=10)
    plane = bpy.context.object
    report = api.bake([cube, plane], order=2, samples=64)
    # The 4 corners of the top face see nothing above their tangent plane (the plane is below,
    # the cube convex), nor do the 4 of the bottom face (it lies on the plane and faces down):
    # their ~32 rays each above the horizon are skipped; the sides and the plane are traced. The
    # plane is open: its back side's 4 corners face down, where nothing is: ~32 more each.
    assert report.rays_traced > 0
    assert report.backend in ("EMBREE", "BVHTREE")
    assert 12 * 28 <= report.skipped_unoccludable <= 12 * 36
