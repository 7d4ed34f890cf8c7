"""The bake job in Blender: Embree against BVHTree, the modal path and its timer, threads, failure safety."""

import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from helpers.bake_scenes import _attr_bytes, _monkey_on_ground
from helpers.modal import ModalStandIn, fake_event
from helpers.threads import ticks_of_other_threads_after

from prt_addon.core.trace import raytrace


def _parity_rays(bake_ops, objects, samples):
    import bpy

    from prt_addon.blender.bake import job as bake_job, settings as bake_settings
    from prt_addon.blender.scene import parts as scene_parts
    from prt_addon.core.transfer import mesh as core_mesh

    job = bake_job.BakeJob(objects, bake_settings.BakeSettings(order=2, samples=samples, backend="EMBREE"))
    try:
        parts = scene_parts.scene_parts(bpy.context.evaluated_depsgraph_get())
        vertices, triangles = core_mesh.concatenate_parts(parts)
        origins, dirs = [], []
        for plan in job.plans:
            for o, d in plan.computation.iter_rays():
                origins.append(o)
                dirs.append(d)
    finally:
        job.close()  # its first slices were already tracing: stop them and their threads
    assert job._pool._shutdown
    assert all(not t.is_alive() for t in job._pool._threads)
    return vertices, triangles, np.concatenate(origins), np.concatenate(dirs)


@pytest.mark.skipif(not raytrace.EMBREE_AVAILABLE, reason="embreex not installed")
def test_embree_and_bvhtree_agree_on_the_same_rays(empty_scene, bpy_module, bake_ops):
    from prt_addon.blender.scene.occluders import BVHTreeOccluder

    ground, monkey = _monkey_on_ground(bpy_module)
    vertices, triangles, origins, dirs = _parity_rays(bake_ops, [monkey, ground], 128)
    embree = raytrace.EmbreeOccluder(vertices, triangles).occluded(origins, dirs)
    bvh = BVHTreeOccluder(vertices, triangles).occluded(origins, dirs)
    agreement = np.mean(embree == bvh)
    assert len(origins) > 20000
    assert 0.05 < embree.mean() < 0.95
    assert agreement >= 0.999, agreement
    # And whole bakes agree.
    from prt_addon import api
    from prt_addon.blender.scene import storage

    r1 = api.bake([monkey], order=3, samples=64, backend="EMBREE")
    a = storage.read_transfer(monkey.data)
    r2 = api.bake([monkey], order=3, samples=64, backend="BVHTREE")
    b = storage.read_transfer(monkey.data)
    assert (r1.backend, r2.backend) == ("EMBREE", "BVHTREE")
    assert monkey.data["prt_bake"]["backend"] == "BVHTREE"
    assert np.mean(np.abs(a - b)) < 1e-3


def test_cancel_through_the_modal_path_leaves_attributes_untouched(empty_scene, bpy_module, bake_ops, monkeypatch):
    from prt_addon.blender.bake import (
        job as bake_job,
        reports as bake_reports,
        runner as bake_runner,
        settings as bake_settings,
    )

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
    assert job._pool._shutdown
    assert all(not t.is_alive() for t in job._pool._threads)
    assert "cancelled" in bake_reports.last_report(empty_scene)["message"]
    assert {o.name: _attr_bytes(o.data) for o in (ground, monkey)} == before
    # The modal path also finishes a bake.
    op = ModalStandIn(bake_ops, bake_job.BakeJob([monkey], bake_settings.BakeSettings(order=2, samples=32)))
    result = {"RUNNING_MODAL"}
    while result == {"RUNNING_MODAL"}:
        result = op.modal(bpy.context, timer)
    assert result == {"FINISHED"}
    assert monkey.data["prt_bake"]["order"] == 2


def test_timer_events_right_after_a_slice_do_no_work(empty_scene, bpy_module, bake_ops, monkeypatch):
    """Blender's events do not say which timer fired, so any TIMER event can run a slice; one that
    comes within TIMER_GAP of the end of the previous slice (another add-on's timer) does none,
    so the UI gets its turn between slices."""
    from prt_addon.blender.bake import job as bake_job, runner as bake_runner, settings as bake_settings

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
    from prt_addon.blender.bake import job as bake_job, settings as bake_settings

    bpy = bpy_module
    bpy.ops.mesh.primitive_uv_sphere_add(segments=16, ring_count=8)
    sphere = bpy.context.object
    job = bake_job.BakeJob([sphere], bake_settings.BakeSettings(order=2, samples=64, backend="EMBREE"))
    report = job.run()
    assert report.rays_traced == 0
    assert job._occluder is not None
    assert not job._occluder.built

    bpy.ops.object.select_all(action="DESELECT")
    sphere.hide_set(True)
    bpy.ops.mesh.primitive_monkey_add()
    monkey = bpy.context.object
    job = bake_job.BakeJob([monkey], bake_settings.BakeSettings(order=2, samples=64, backend="EMBREE"))
    report = job.run()
    assert report.rays_traced > 0
    assert job._occluder.built

    job = bake_job.BakeJob([monkey], bake_settings.BakeSettings(order=2, samples=64, backend="EMBREE"))
    job.steps().close()  # a generator closed before its first step runs no clean-up of its own
    job.close()  # what the operator's clean-up does
    assert job._pool._shutdown
    assert all(not t.is_alive() for t in job._pool._threads)


def test_first_object_traces_while_the_others_are_prepared(empty_scene, bpy_module, bake_ops, mesh_io, monkeypatch):
    """The job queues the first object's slices as soon as its points are ready: one of them is
    traced while the second object's points are still being read. A failure there stops them and
    leaves no thread behind."""
    from prt_addon.blender.bake import job as bake_job, settings as bake_settings
    from prt_addon.blender.scene import mesh_read

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
    assert len(started) == 1
    assert seen == [True]
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
    assert started
    assert pools[0]._shutdown
    assert all(not t.is_alive() for t in pools[0]._threads)
    assert {o.name: _attr_bytes(o.data) for o in (ground, monkey)} == before


def test_failing_bake_leaves_attributes_untouched(empty_scene, bpy_module, bake_ops, mesh_io, monkeypatch):
    from prt_addon.blender.bake import reports as bake_reports
    from prt_addon.blender.scene import storage

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


def test_bake_set_up_leaves_no_blas_thread_spinning(empty_scene, bpy_module, bake_ops):
    """Reading and transforming ~32k vertices (rotated and scaled) must not wake numpy's BLAS
    threads, whose spinning would take a core from the tracing threads (core.serial_blas)."""
    from prt_addon.blender.bake import job as bake_job, settings as bake_settings

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
