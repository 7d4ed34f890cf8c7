"""The transfer bake in Blender: operator, API, backends, storage, staleness, failure safety."""

import json
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

pytestmark = pytest.mark.blender

from conftest import ModalStandIn, fake_event, ticks_of_other_threads_after  # noqa: E402
from prt_addon.core import analytic, raytrace, transfer  # noqa: E402


@pytest.fixture
def bake_ops(addon):
    from prt_addon.blender.ops import bake as bake_ops

    return bake_ops


@pytest.fixture
def mesh_io(addon):
    from prt_addon.blender import mesh_read

    return mesh_read


def _monkey_on_ground(bpy, ground_cuts=8, smooth=True):
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=ground_cuts, y_subdivisions=ground_cuts, size=6)
    ground = bpy.context.object
    bpy.ops.mesh.primitive_monkey_add(location=(0, 0, 1.0))
    monkey = bpy.context.object
    if smooth:
        monkey.data.shade_smooth()
    return ground, monkey


def _attr_bytes(mesh):
    """{name: (domain, data_type, raw bytes)} of every prt_* attribute, plus the record."""
    out = {}
    for attr in mesh.attributes:
        if attr.name.startswith("prt_"):
            buf = np.empty(len(attr.data) * 4, np.float32)
            mesh.attributes[attr.name].data.foreach_get("color", buf)
            out[attr.name] = (attr.domain, attr.data_type, buf.tobytes())
    record = mesh.get("prt_bake")
    out["record"] = json.dumps(record.to_dict() if record is not None else None, sort_keys=True)
    out["active"] = mesh.color_attributes.active_color_name
    return out


def _scale_scene(bpy, factor):
    for obj in bpy.context.scene.objects:
        obj.location = obj.location * factor
        obj.scale = obj.scale * factor
    bpy.context.view_layer.update()


def test_operator_bakes_selection_and_writes_storage(empty_scene, bpy_module, mesh_io):
    from prt_addon.blender import storage

    bpy = bpy_module
    ground, monkey = _monkey_on_ground(bpy)
    for obj in (ground, monkey):
        obj.select_set(True)
    settings = empty_scene.prt_bake
    settings.order, settings.samples = 3, 64
    assert bpy.ops.prt.bake_transfer() == {"FINISHED"}
    record = monkey.data["prt_bake"]
    assert record["order"] == 3 and record["count"] == 3 and record["domain"] == "POINT"
    assert record["backend"] in ("EMBREE", "BVHTREE") and record["rays_traced"] > 0
    for k in range(3):
        attr = monkey.data.attributes[f"prt_t{k:02d}"]
        assert attr.data_type == "FLOAT_COLOR" and attr.domain == "POINT"
    values = storage.read_transfer(monkey.data)
    assert values.shape == (len(monkey.data.vertices), 9) and np.isfinite(values).all()
    report = json.loads(settings.last_report)
    assert report["ok"] and report["rays_traced"] > 0 and report["error_estimate"] > 0
    assert set(report["objects"]) == {ground.name, monkey.name}
    from prt_addon import api

    assert api.bake_status(monkey) == "fresh" and api.bake_status(ground) == "fresh"
    # Lower order: the extra attributes go; higher again: they come back.
    api.bake([monkey], order=2, samples=32)
    assert monkey.data["prt_bake"]["count"] == 1
    assert [a.name for a in monkey.data.attributes if a.name.startswith("prt_t")] == ["prt_t00"]
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
    from prt_addon.blender import storage

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
    from prt_addon.blender import mesh_read
    from prt_addon.blender import storage

    bpy = bpy_module
    bpy.ops.mesh.primitive_uv_sphere_add(segments=12, ring_count=6, rotation=(0.3, 0.5, 0.7), scale=(1, 2, 0.5))
    sphere = bpy.context.object
    sphere.data.shade_smooth()
    from prt_addon import api

    report = api.bake([sphere], order=3, samples=2048)
    assert report.rays_traced == 0 and report.backend == "NONE"
    assert report.skipped_unoccludable > 0
    normals = mesh_read.read_vertex_normals(sphere.data).astype(np.float64)
    # Normals in the local frame: world normal (inverse transpose) rotated back by R^-1.
    m = np.array(sphere.matrix_world)[:3, :3]
    world = normals @ np.linalg.inv(m)
    world /= np.linalg.norm(world, axis=1, keepdims=True)
    r, _ = transfer.frame_rotation(m)
    local = world @ r
    values = storage.read_transfer(sphere.data)
    expected = np.array([analytic.clamped_cosine_coeffs(3, n) for n in local])
    np.testing.assert_allclose(values, expected, atol=2e-4)


def test_coarse_smooth_mesh_does_not_shadow_itself(empty_scene, bpy_module, mesh_io):
    from prt_addon.blender import storage

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


def _parity_rays(bake_ops, objects, samples):
    from prt_addon.blender.bake import job as bake_job
    from prt_addon.blender.bake import scene as bake_scene
    from prt_addon.blender.bake import settings as bake_settings
    from prt_addon.core import mesh as core_mesh
    import bpy

    job = bake_job.BakeJob(objects, bake_settings.BakeSettings(order=2, samples=samples, backend="EMBREE"))
    try:
        parts = bake_scene.scene_parts(bpy.context.evaluated_depsgraph_get())
        vertices, triangles = core_mesh.concatenate_parts(parts)
        origins, dirs = [], []
        for plan in job.plans:
            for o, d in plan.computation.iter_rays():
                origins.append(o)
                dirs.append(d)
    finally:
        job.close()  # its first slices were already tracing: stop them and their threads
    assert job._pool._shutdown and all(not t.is_alive() for t in job._pool._threads)
    return vertices, triangles, np.concatenate(origins), np.concatenate(dirs)


@pytest.mark.skipif(not raytrace.EMBREE_AVAILABLE, reason="embreex not installed")
def test_embree_and_bvhtree_agree_on_the_same_rays(empty_scene, bpy_module, bake_ops):
    from prt_addon.blender.bvh_backend import BVHTreeOccluder

    ground, monkey = _monkey_on_ground(bpy_module)
    vertices, triangles, origins, dirs = _parity_rays(bake_ops, [monkey, ground], 128)
    embree = raytrace.EmbreeOccluder(vertices, triangles).occluded(origins, dirs)
    bvh = BVHTreeOccluder(vertices, triangles).occluded(origins, dirs)
    agreement = np.mean(embree == bvh)
    assert len(origins) > 20000 and 0.05 < embree.mean() < 0.95
    assert agreement >= 0.999, agreement
    # And whole bakes agree.
    from prt_addon import api

    from prt_addon.blender import storage

    r1 = api.bake([monkey], order=3, samples=64, backend="EMBREE")
    a = storage.read_transfer(monkey.data)
    r2 = api.bake([monkey], order=3, samples=64, backend="BVHTREE")
    b = storage.read_transfer(monkey.data)
    assert (r1.backend, r2.backend) == ("EMBREE", "BVHTREE")
    assert monkey.data["prt_bake"]["backend"] == "BVHTREE"
    assert np.mean(np.abs(a - b)) < 1e-3


def test_cancel_through_the_modal_path_leaves_attributes_untouched(empty_scene, bpy_module, bake_ops, monkeypatch):
    from prt_addon.blender.bake import runner as bake_runner
    from prt_addon.blender.bake import job as bake_job
    from prt_addon.blender.bake import reports as bake_reports
    from prt_addon.blender.bake import settings as bake_settings

    monkeypatch.setattr(bake_runner, "TIME_SLICE", 0.0)  # one chunk per timer event
    monkeypatch.setattr(bake_runner, "TIMER_GAP", 0.0)  # (tested on its own below)
    bpy = bpy_module
    ground, monkey = _monkey_on_ground(bpy)
    from prt_addon import api

    api.bake([monkey, ground], order=3, samples=32)
    before = {o.name: _attr_bytes(o.data) for o in (ground, monkey)}
    settings = empty_scene.prt_bake
    settings.order, settings.samples = 4, 256
    job = bake_job.BakeJob([monkey, ground], bake_settings.BakeSettings(order=4, samples=256, chunk_rays=4096))
    # Drive the operator's modal() with a stand-in for the operator instance.
    op = ModalStandIn(bake_ops, job)
    timer = fake_event("TIMER", "NOTHING")
    assert op.modal(bpy.context, timer) == {"RUNNING_MODAL"}
    assert 0 < job.fraction < 1
    assert op.modal(bpy.context, fake_event("ESC")) == {"CANCELLED"}
    assert job._pool._shutdown and all(not t.is_alive() for t in job._pool._threads)
    assert "cancelled" in bake_reports.last_report(empty_scene)["message"]
    assert {o.name: _attr_bytes(o.data) for o in (ground, monkey)} == before
    # The modal path also finishes a bake.
    op = ModalStandIn(bake_ops, bake_job.BakeJob([monkey], bake_settings.BakeSettings(order=2, samples=32)))
    result = {"RUNNING_MODAL"}
    while result == {"RUNNING_MODAL"}:
        result = op.modal(bpy.context, timer)
    assert result == {"FINISHED"} and monkey.data["prt_bake"]["order"] == 2


def test_timer_events_right_after_a_slice_do_no_work(empty_scene, bpy_module, bake_ops, monkeypatch):
    """Blender's events do not say which timer fired, so any TIMER event can run a slice; one that
    comes within TIMER_GAP of the end of the previous slice (another add-on's timer) does none,
    so the UI gets its turn between slices."""
    from prt_addon.blender.bake import job as bake_job
    from prt_addon.blender.bake import runner as bake_runner
    from prt_addon.blender.bake import settings as bake_settings

    monkeypatch.setattr(bake_runner, "TIME_SLICE", 0.0)
    bpy = bpy_module
    ground, monkey = _monkey_on_ground(bpy)
    job = bake_job.BakeJob([monkey, ground], bake_settings.BakeSettings(order=4, samples=256, chunk_rays=4096))
    op = ModalStandIn(bake_ops, job)
    try:
        assert op.modal(bpy.context, fake_event("TIMER", "NOTHING")) == {"RUNNING_MODAL"}
        after_one = job.fraction
        assert 0 < after_one < 1
        assert op.modal(bpy.context, fake_event("TIMER", "NOTHING")) == {"RUNNING_MODAL"}
        assert job.fraction == after_one  # right after the slice: no work
        time.sleep(1.5 * bake_runner.TIMER_GAP)
        assert op.modal(bpy.context, fake_event("TIMER", "NOTHING")) == {"RUNNING_MODAL"}
        assert job.fraction > after_one
    finally:
        assert op.modal(bpy.context, fake_event("ESC")) == {"CANCELLED"}
    assert job._pool._shutdown


def test_scene_bvh_is_built_only_when_a_ray_can_be_traced(empty_scene, bpy_module, bake_ops):
    """A lone convex object traces nothing, so its job never builds the scene's BVH (the
    background build starts only when some object can trace); Suzanne can shadow itself, so
    hers is built. A job closed before its first step leaves no worker thread behind."""
    from prt_addon.blender.bake import job as bake_job
    from prt_addon.blender.bake import settings as bake_settings

    bpy = bpy_module
    bpy.ops.mesh.primitive_uv_sphere_add(segments=16, ring_count=8)
    sphere = bpy.context.object
    job = bake_job.BakeJob([sphere], bake_settings.BakeSettings(order=2, samples=64, backend="EMBREE"))
    report = job.run()
    assert report.rays_traced == 0 and job._occluder is not None and not job._occluder.built

    bpy.ops.object.select_all(action="DESELECT")
    sphere.hide_set(True)
    bpy.ops.mesh.primitive_monkey_add()
    monkey = bpy.context.object
    job = bake_job.BakeJob([monkey], bake_settings.BakeSettings(order=2, samples=64, backend="EMBREE"))
    report = job.run()
    assert report.rays_traced > 0 and job._occluder.built

    job = bake_job.BakeJob([monkey], bake_settings.BakeSettings(order=2, samples=64, backend="EMBREE"))
    job.steps().close()  # a generator closed before its first step runs no clean-up of its own
    job.close()  # what the operator's clean-up does
    assert job._pool._shutdown and all(not t.is_alive() for t in job._pool._threads)


def test_first_object_traces_while_the_others_are_prepared(empty_scene, bpy_module, bake_ops, mesh_io, monkeypatch):
    """The job queues the first object's slices as soon as its points are ready: one of them is
    traced while the second object's points are still being read. A failure there stops them and
    leaves no thread behind."""
    from prt_addon.blender.bake import job as bake_job
    from prt_addon.blender.bake import settings as bake_settings
    from prt_addon.blender import mesh_read

    bpy = bpy_module
    ground, monkey = _monkey_on_ground(bpy)
    started, seen = [], []
    real_start, real_points = bake_job.transfer.TransferComputation.start, mesh_read.bake_points

    def recording_start(self):
        started.append(self)
        return real_start(self)

    def points(mesh, *args):
        if started:  # the second object: wait (up to 20 s) for a slice of the first
            future = started[0]._pending[0][2]
            future.result(timeout=20)
            seen.append(started[0].done == 0 and future.done())
        return real_points(mesh, *args)

    monkeypatch.setattr(bake_job.transfer.TransferComputation, "start", recording_start)
    monkeypatch.setattr(mesh_read, "bake_points", points)
    settings = bake_settings.BakeSettings(order=3, samples=64, backend="EMBREE", threads=2)
    job = bake_job.BakeJob([monkey, ground], settings)
    assert len(started) == 1 and seen == [True]
    report = job.run()
    assert report.rays_traced > 0

    def failing_points(mesh, *args):
        if started:
            raise RuntimeError("injected")
        return real_points(mesh, *args)

    started.clear()
    monkeypatch.setattr(mesh_read, "bake_points", failing_points)
    before = {o.name: _attr_bytes(o.data) for o in (ground, monkey)}
    pools = []
    monkeypatch.setattr(
        bake_job, "ThreadPoolExecutor", lambda *a, **k: pools.append(ThreadPoolExecutor(*a, **k)) or pools[-1]
    )
    with pytest.raises(RuntimeError, match="injected"):
        bake_job.BakeJob([monkey, ground], settings)
    assert started and pools[0]._shutdown and all(not t.is_alive() for t in pools[0]._threads)
    assert {o.name: _attr_bytes(o.data) for o in (ground, monkey)} == before


def test_failing_bake_leaves_attributes_untouched(empty_scene, bpy_module, bake_ops, mesh_io, monkeypatch):
    from prt_addon.blender.bake import reports as bake_reports
    from prt_addon.blender import storage

    bpy = bpy_module
    ground, monkey = _monkey_on_ground(bpy)
    from prt_addon import api

    api.bake([monkey, ground], order=3, samples=32)
    before = {o.name: _attr_bytes(o.data) for o in (ground, monkey)}

    def explode(fraction, text):
        if fraction > 0.3:
            raise RuntimeError("injected failure")

    with pytest.raises(RuntimeError, match="injected"):
        api.bake([monkey, ground], order=4, samples=64, progress=explode, chunk_rays=4096)
    assert {o.name: _attr_bytes(o.data) for o in (ground, monkey)} == before

    # A failure while writing the second mesh: the first one is restored too.
    real_write = storage.write_transfer
    calls = []

    def write_then_fail(mesh, *args):
        calls.append(mesh.name)
        if len(calls) == 2:
            raise RuntimeError("injected write failure")
        return real_write(mesh, *args)

    monkeypatch.setattr(storage, "write_transfer", write_then_fail)
    with pytest.raises(RuntimeError, match="injected write"):
        api.bake([monkey, ground], order=4, samples=32)
    assert len(calls) == 2
    assert {o.name: _attr_bytes(o.data) for o in (ground, monkey)} == before

    # The operator reports the failure and cancels.
    monkeypatch.setattr(storage, "write_transfer", lambda *a: (_ for _ in ()).throw(RuntimeError("boom")))
    for obj in (ground, monkey):
        obj.select_set(True)
    # In background mode bpy.ops turns an ERROR report into RuntimeError.
    with pytest.raises(RuntimeError, match="nothing was changed: boom"):
        bpy.ops.prt.bake_transfer()
    assert "boom" in bake_reports.last_report(empty_scene)["message"]
    assert {o.name: _attr_bytes(o.data) for o in (ground, monkey)} == before


def test_topology_edit_is_stale(empty_scene, bpy_module):
    import bmesh

    bpy = bpy_module
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=2)
    obj = bpy.context.object
    from prt_addon import api

    assert api.bake_status(obj) == "none"
    api.bake([obj], order=2, samples=32)
    assert api.bake_status(obj) == "fresh"
    obj.data.vertices[0].co.x += 0.1  # moving a vertex keeps the topology
    assert api.bake_status(obj) == "fresh"
    bm = bmesh.new()
    bm.from_mesh(obj.data)
    bmesh.ops.triangulate(bm, faces=bm.faces[:])  # already triangles: no change
    bm.to_mesh(obj.data)
    assert api.bake_status(obj) == "fresh"
    # Rotating one edge keeps every count but changes which vertices the corners use.
    bm = bmesh.new()
    bm.from_mesh(obj.data)
    bm.edges.ensure_lookup_table()
    bmesh.ops.rotate_edges(bm, edges=[bm.edges[5]], use_ccw=True)
    bm.to_mesh(obj.data)
    bm.free()
    state, reason = api.bake_status(obj, reason=True)
    assert state == "stale" and "topology" in reason
    api.bake([obj], order=2, samples=32)
    assert api.bake_status(obj) == "fresh"
    bm = bmesh.new()
    bm.from_mesh(obj.data)
    bm.verts.ensure_lookup_table()
    bmesh.ops.delete(bm, geom=[bm.verts[0]], context="VERTS")
    bm.to_mesh(obj.data)
    bm.free()
    assert api.bake_status(obj) == "stale"


def test_removed_or_converted_transfer_attribute_is_reported(empty_scene, bpy_module):
    """A user deleting or converting one prt_tKK attribute: the bake is stale (not 'fresh' with
    garbage), the display does not draw it, and storage.read_transfer returns None."""
    bpy = bpy_module
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=2)
    obj = bpy.context.object
    from prt_addon import api
    from prt_addon.blender import storage
    from prt_addon.blender.display import gpu_cache

    api.bake([obj], order=3, samples=32, shadows=False)  # 9 coefficients: prt_t00 .. prt_t02
    assert api.bake_status(obj) == "fresh"
    info, problem = storage.usable_bake(obj.data)
    assert info.order == 3 and info.count == 3 and problem == ""
    elements = len(obj.data.loops) if info.domain == "CORNER" else len(obj.data.vertices)
    assert gpu_cache.read_transfer(obj.data, info).shape == (elements, 12)
    assert storage.read_transfer(obj.data).shape == (elements, 9)

    obj.data.attributes.remove(obj.data.attributes["prt_t01"])
    state, reason = api.bake_status(obj, reason=True)
    assert state == "stale" and "prt_t01" in reason
    assert storage.usable_bake(obj.data) == (None, "attribute prt_t01 is missing or changed")
    assert storage.read_transfer(obj.data) is None

    api.bake([obj], order=3, samples=32, shadows=False)
    assert api.bake_status(obj) == "fresh"
    obj.data.attributes.new("prt_t02_tmp", "BYTE_COLOR", info.domain)
    obj.data.attributes.remove(obj.data.attributes["prt_t02"])
    obj.data.attributes["prt_t02_tmp"].name = "prt_t02"  # same name, wrong type
    assert api.bake_status(obj) == "stale"
    assert storage.usable_bake(obj.data)[0] is None

    api.bake([obj], order=3, samples=32, shadows=False)
    del obj.data["prt_bake"]["fingerprint"]
    assert api.bake_status(obj, reason=True) == ("stale", "the bake record is incomplete: bake again")


def _scene_values(bpy, mesh_io, factor):
    from prt_addon.blender import storage

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


def test_bad_inputs_give_clear_reports(empty_scene, bpy_module, bake_ops):
    from prt_addon.blender.bake import reports as bake_reports

    bpy = bpy_module
    from prt_addon import api

    with pytest.raises(ValueError, match="nothing selected"):
        api.bake([])
    bpy.ops.object.empty_add()
    empty = bpy.context.object
    with pytest.raises(ValueError, match="not a mesh"):
        api.bake([empty])
    mesh = bpy.data.meshes.new("points")
    mesh.from_pydata([(0, 0, 0), (1, 0, 0)], [(0, 1)], [])
    points = bpy.data.objects.new("points", mesh)
    empty_scene.collection.objects.link(points)
    with pytest.raises(ValueError, match="has no faces"):
        api.bake([points])
    with pytest.raises(ValueError, match="order"):
        api.bake([points], order=0)
    bpy.ops.mesh.primitive_cube_add(location=(5, 0, 0))
    cube = bpy.context.object
    report = api.bake([cube, empty, points], order=2, samples=16)
    assert report.objects == [cube.name]
    assert [name for name, _ in report.skipped] == [empty.name, points.name]
    assert any("Skipped" in line for line in report.summary_lines())
    # The operator: empty selection, then a non-mesh only.
    bpy.ops.object.select_all(action="DESELECT")
    with pytest.raises(RuntimeError, match="nothing selected"):
        bpy.ops.prt.bake_transfer()
    assert "nothing selected" in bake_reports.last_report(empty_scene)["message"]
    empty.select_set(True)
    with pytest.raises(RuntimeError, match="not a mesh"):
        bpy.ops.prt.bake_transfer()
    assert "not a mesh" in bake_reports.last_report(empty_scene)["message"]


def test_modifiers_deform_is_used_topology_change_is_refused(empty_scene, bpy_module, mesh_io):
    bpy = bpy_module
    from prt_addon import api

    bpy.ops.mesh.primitive_grid_add(x_subdivisions=6, y_subdivisions=6, size=2)
    grid = bpy.context.object
    wave = grid.modifiers.new("Wave", "WAVE")  # moves vertices only: same topology
    wave.height, wave.width, wave.narrowness = 0.5, 0.5, 0.5
    report = api.bake([grid], order=2, samples=64)
    # The flat base mesh cannot shadow itself; the curved one (what the user sees) can.
    assert report.rays_traced > 0 and report.objects == [grid.name]
    grid.modifiers.new("Subdivision", "SUBSURF")
    with pytest.raises(ValueError, match="Apply"):
        api.bake([grid], order=2, samples=16)


def test_lone_convex_object_traces_nothing_and_ground_contact_does(empty_scene, bpy_module):
    bpy = bpy_module
    from prt_addon import api

    bpy.ops.mesh.primitive_cube_add(location=(0, 0, 1))
    cube = bpy.context.object
    report = api.bake([cube], order=2, samples=64)
    assert report.rays_traced == 0 and report.backend == "NONE"
    assert report.points == 24  # flat cube: 8 vertices x 3 face normals
    assert report.rays_skipped == 64 * report.points
    assert report.skipped_below_horizon + report.skipped_unoccludable == report.rays_skipped
    assert cube.data["prt_bake"]["backend"] == "NONE"
    bpy.ops.mesh.primitive_plane_add(size=10)
    plane = bpy.context.object
    report = api.bake([cube, plane], order=2, samples=64)
    # The 4 corners of the top face see nothing above their tangent plane (the plane is below,
    # the cube convex), nor do the 4 of the bottom face (it lies on the plane and faces down):
    # their ~32 rays each above the horizon are skipped; the sides and the plane are traced.
    assert report.rays_traced > 0 and report.backend in ("EMBREE", "BVHTREE")
    assert 8 * 28 <= report.skipped_unoccludable <= 8 * 36


def test_bad_seed_is_refused_before_any_ray(empty_scene, bpy_module, mesh_io, monkeypatch):
    bpy = bpy_module
    bpy.ops.mesh.primitive_plane_add()
    plane = bpy.context.object
    from prt_addon import api
    from prt_addon.blender.bake import job as bake_job

    monkeypatch.setattr(bake_job.BakeJob, "steps", lambda *a, **k: pytest.fail("traced before validating"))
    for seed in (None, -1, 2.5):
        with pytest.raises(ValueError, match="seed must be an integer >= 0"):
            api.bake([plane], seed=seed)
    assert "prt_bake" not in plane.data


def test_bake_set_up_leaves_no_blas_thread_spinning(empty_scene, bpy_module, bake_ops):
    """Reading and transforming ~32k vertices (rotated and scaled) must not wake numpy's BLAS
    threads, whose spinning would take a core from the tracing threads (core.serial_blas)."""
    from prt_addon.blender.bake import job as bake_job
    from prt_addon.blender.bake import settings as bake_settings

    bpy = bpy_module
    bpy.ops.mesh.primitive_monkey_add(rotation=(0.3, 0.2, 0.1), scale=(1, 2, 3))
    monkey = bpy.context.object
    monkey.modifiers.new("s", "SUBSURF").levels = 3
    bpy.ops.object.modifier_apply(modifier="s")
    monkey.data.shade_smooth()
    assert len(monkey.data.vertices) > 30_000
    threaded = ticks_of_other_threads_after(lambda: np.random.default_rng(0).random((40_000, 3)) @ np.eye(3))
    if threaded < 3:
        pytest.skip(f"this numpy's BLAS does not spin after a threaded product ({threaded} ticks)")
    jobs = []
    settings = bake_settings.BakeSettings(order=4, samples=64, threads=1, shadows=False)
    try:
        ticks = ticks_of_other_threads_after(lambda: jobs.append(bake_job.BakeJob([monkey], settings)))
    finally:
        for job in jobs:
            job.close()
    assert ticks <= 1
