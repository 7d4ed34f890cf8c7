"""Bad input to the bake: settings out of range, a missing backend, and a bake already running or cut short.

Each case ends in a clear message and leaves the .blend exactly as it was (the snapshot helpers and
the baked scene are in test_bad_input.py). The modal bake is driven with a stand-in for the
operator instance, as in tests/blender/test_bake_job.py.
"""

import types

import pytest
from helpers.bad_input import assert_unchanged, bake, refused, select_only, snapshot
from helpers.modal import ModalStandIn, fake_event

pytestmark = pytest.mark.usefixtures("no_bake_left_running")


# --- bake: settings ---------------------------------------------------------------------------


@pytest.mark.parametrize("order", [0, 1000])
def test_bake_order_out_of_range(bpy_module, scene, order):
    from prt_addon import api

    refused(
        bpy_module,
        lambda: api.bake([scene.sphere], order=order),
        rf"order must be an integer from 1 to 16, got {order}",
    )
    # The sidebar cannot even hold such a value: Blender clamps it to the property's range.
    scene.scene.prt_bake.order = order
    assert 1 <= scene.scene.prt_bake.order <= 16


def test_zero_samples(bpy_module, scene):
    from prt_addon import api

    refused(bpy_module, lambda: api.bake([scene.sphere], samples=0), r"samples must be an integer >= 2, got 0")


def test_embree_requested_where_missing(bpy_module, scene, monkeypatch):
    from prt_addon.core.trace import raytrace

    monkeypatch.setattr(raytrace, "EMBREE_AVAILABLE", False)
    monkeypatch.setattr(raytrace, "EMBREE_IMPORT_ERROR", "ImportError: No module named 'embreex'")
    scene.scene.prt_bake.backend = "EMBREE"
    before = snapshot(bpy_module)
    scene.scene.prt_bake.backend = "EMBREE"
    select_only(bpy_module, scene.sphere)
    before = snapshot(bpy_module)
    with pytest.raises(RuntimeError, match=r"the Embree backend is not available on this system .*choose Auto"):
        bake(bpy_module)
    assert_unchanged(before, snapshot(bpy_module))


# --- bake: while running ----------------------------------------------------------------------


def _timer_event():
    return fake_event("TIMER", "NOTHING")  # (made when used: conftest's fake_event imports bpy)


def _start_modal(bpy, scene_ns, monkeypatch):
    from prt_addon.blender.bake import job as bake_job, runner as bake_runner, settings as bake_settings
    from prt_addon.blender.ops import bake as bake_op

    monkeypatch.setattr(bake_runner, "TIME_SLICE", 0.0)
    monkeypatch.setattr(bake_runner, "TIMER_GAP", 0.0)
    job = bake_job.BakeJob(
        [scene_ns.sphere, scene_ns.ground], bake_settings.BakeSettings(order=4, samples=256, chunk_rays=2048)
    )
    op = ModalStandIn(bake_op, job)
    bake_runner._running.add(op)  # what invoke() does
    assert op.modal(bpy.context, _timer_event()) == {"RUNNING_MODAL"}
    assert 0 < job.fraction < 1
    return bake_runner, op


def test_invoke_failing_after_the_job_starts_stops_it(bpy_module, scene, monkeypatch):
    """invoke() creates the job (whose first slices start tracing at once), then adds the timer
    and the modal handler: if that fails, the job's threads are stopped and nothing is kept."""
    from prt_addon.blender.bake import job as bake_job, runner as bake_runner, settings as bake_settings
    from prt_addon.blender.ops import bake as bake_op

    bpy = bpy_module

    class WithWindow:  # bpy as seen by bake_ops, but not in background mode
        app = types.SimpleNamespace(background=False)

        def __getattr__(self, name):
            return getattr(bpy, name)

    class WindowManager:
        def event_timer_add(self, *args, **kwargs):
            raise RuntimeError("no timer")

        def progress_end(self):
            pass

    class Operator:
        pass

    monkeypatch.setattr(bake_runner, "bpy", WithWindow())
    job = bake_job.BakeJob(
        [scene.sphere, scene.ground], bake_settings.BakeSettings(order=4, samples=256, chunk_rays=2048)
    )
    assert job.plans[0].computation._pending, "the first object's slices should be queued"
    op = Operator()
    cls = bake_op.PRT_OT_bake_transfer
    op._job = lambda context: job
    op._cleanup = lambda context: cls._cleanup(op, context)
    context = types.SimpleNamespace(window=object(), window_manager=WindowManager(), workspace=None, screen=None)
    before = snapshot(bpy)
    with pytest.raises(RuntimeError, match="no timer"):
        cls.invoke(op, context, None)
    assert op not in bake_runner._running
    assert job._pool._shutdown
    assert all(not t.is_alive() for t in job._pool._threads)
    assert_unchanged(before, snapshot(bpy))


def test_bake_while_another_bake_runs(bpy_module, scene, monkeypatch):
    from prt_addon.blender.bake import runner as bake_runner

    bpy = bpy_module
    before = snapshot(bpy)
    bake_ops, op = _start_modal(bpy, scene, monkeypatch)
    try:
        select_only(bpy, scene.sphere)
        before = snapshot(bpy)
        refused(bpy, lambda: bake(bpy), r"a bake is already running: wait for it to finish, or press Esc")
        assert_unchanged(before, snapshot(bpy))
    finally:
        assert op.modal(bpy.context, fake_event("ESC")) == {"CANCELLED"}
    assert not bake_runner._running
    assert ({"WARNING"}, "PRT: bake cancelled, nothing was changed") in op.reports


def test_topology_change_during_modal_bake(bpy_module, scene, monkeypatch):
    import bmesh

    from prt_addon.blender.bake import runner as bake_runner

    bpy = bpy_module
    bake_ops, op = _start_modal(bpy, scene, monkeypatch)
    # The user edits the sphere while the bake runs: the bake must refuse to write.
    bm = bmesh.new()
    bm.from_mesh(scene.sphere.data)
    bm.verts.ensure_lookup_table()
    bmesh.ops.delete(bm, geom=[bm.verts[0]], context="VERTS")
    bm.to_mesh(scene.sphere.data)
    bm.free()
    before = snapshot(bpy)
    result = {"RUNNING_MODAL"}
    while result == {"RUNNING_MODAL"}:
        result = op.modal(bpy.context, _timer_event())
    assert result == {"CANCELLED"}
    assert any(
        "ERROR" in kind and "topology of 'Sphere' changed during the bake: bake again" in msg
        for kind, msg in op.reports
    ), op.reports
    assert_unchanged(before, snapshot(bpy))
    assert not bake_runner._running


def test_unregister_in_the_middle_of_a_modal_bake(bpy_module, scene, monkeypatch):
    from prt_addon.blender.bake import job as bake_job, runner as bake_runner, settings as bake_settings

    bpy = bpy_module
    import prt_addon

    wm = bpy.context.window_manager
    bake_ops, op = _start_modal(bpy, scene, monkeypatch)
    op._timer = wm.event_timer_add(0.02)  # a real window-manager timer, as invoke() adds
    # Another bake invoked but not stepped yet: closing its unstarted steps() generator runs none
    # of the generator's clean-up, so unregister must close the job itself.
    pending_job = bake_job.BakeJob([scene.ground], bake_settings.BakeSettings(order=2, samples=16))
    from prt_addon.blender.ops import bake as bake_op

    bake_runner._running.add(ModalStandIn(bake_op, pending_job))
    before = snapshot(bpy)
    job = op._bake
    prt_addon.unregister()  # the user disables the add-on while it bakes
    try:
        assert op._timer is None, "the bake's timer was not removed"
        assert not bake_runner._running
        assert job._cancel
        assert job._pool._shutdown, "the bake's worker threads were not stopped"
        assert pending_job._cancel
        assert pending_job._pool._shutdown, "the pending bake's worker threads were not stopped"
        # If Blender still delivers an event to the dead operator, it writes nothing.
        assert op.modal(bpy.context, _timer_event()) == {"CANCELLED"}
    finally:
        prt_addon.register()
    after = snapshot(bpy)
    assert_unchanged(before, after)
    # Registered again, everything works.
    select_only(bpy, scene.sphere)
    assert bake(bpy) == {"FINISHED"}
