"""A modal bake under faults: the object deleted, undo or redo, the file saved, a file loaded, the scene
switched, a second bake started. Each ends with a clear report, and nothing half-written."""

import types

import pytest
from helpers.bake_scenes import _attr_bytes, _monkey_on_ground
from helpers.modal import ModalStandIn, fake_event


@pytest.fixture(autouse=True)
def _one_chunk_per_event(monkeypatch, addon):
    from prt_addon.blender.bake import runner

    monkeypatch.setattr(runner, "TIME_SLICE", 0.0)  # (a fault comes between chunks, not after the bake)
    monkeypatch.setattr(runner, "TIMER_GAP", 0.0)


def _start(bake_ops, objects, **kw):
    from prt_addon.blender.bake import job as bake_job, settings as bake_settings

    settings = bake_settings.BakeSettings(order=2, samples=64, chunk_rays=2048, **kw)
    op = ModalStandIn(bake_ops, bake_job.BakeJob(objects, settings))
    return op, op.modal(__import__("bpy").context, fake_event("TIMER", "NOTHING"))


def _run_out(op, context=None):
    import bpy

    result = {"RUNNING_MODAL"}
    while result == {"RUNNING_MODAL"}:
        result = op.modal(context or bpy.context, fake_event("TIMER", "NOTHING"))
    return result


@pytest.mark.parametrize(("bounces", "what"), [(0, "object and mesh"), (2, "object and mesh"), (0, "object")])
def test_an_object_deleted_during_the_bake_fails_it_at_the_next_event(bpy_module, empty_scene, bake_ops, bounces, what):
    from prt_addon.blender.bake import reports

    bpy = bpy_module
    ground, monkey = _monkey_on_ground(bpy, ground_cuts=30)
    before = _attr_bytes(ground.data)
    op, first = _start(bake_ops, [ground, monkey], bounces=bounces)
    assert first == {"RUNNING_MODAL"}
    bpy.data.objects.remove(monkey)  # (what Delete does; its mesh stays as an orphan)
    if what == "object and mesh":
        bpy.data.meshes.remove(bpy.data.meshes["Suzanne"])
    assert op.modal(bpy.context, fake_event("TIMER", "NOTHING")) == {"CANCELLED"}  # (not at the end)
    message = reports.last_report(empty_scene)["message"]
    assert message.startswith("Bake failed") and "'Suzanne' was deleted during the bake" in message
    assert any("nothing was changed" in text for _kind, text in op.reports)
    assert _attr_bytes(ground.data) == before
    assert all(not t.is_alive() for t in op._bake._pool._threads)


@pytest.mark.parametrize("handlers", ["undo_pre", "redo_pre"])
def test_undo_or_redo_during_the_bake_cancels_it(bpy_module, empty_scene, bake_ops, handlers):
    """Headless Blender has no undo stack (ed.undo's poll fails): the handlers undo and redo run
    first are called as Blender calls them; real_blender_check.py presses undo in a window."""
    from prt_addon.blender.bake import reports, runner

    bpy = bpy_module
    ground, monkey = _monkey_on_ground(bpy, ground_cuts=30)
    before = (_attr_bytes(ground.data), _attr_bytes(monkey.data))
    op, _ = _start(bake_ops, [ground, monkey], bounces=1)
    runner._running.add(op)
    try:
        for handler in list(getattr(bpy.app.handlers, handlers)):
            handler(bpy.context.scene, None)
        assert op._bake._cancel and op not in runner._running
        # The panel says so before the operator's next event (with its timer gone, that may be
        # long in coming in a window nobody touches).
        early = reports.last_report(empty_scene)
        assert early["cancelled"] and early["message"] == runner.UNDO_CANCEL
    finally:
        runner._running.discard(op)
    assert op.modal(bpy.context, fake_event("MOUSEMOVE", "NOTHING")) == {"CANCELLED"}
    report = reports.last_report(empty_scene)
    assert report["cancelled"] and report["message"] == runner.UNDO_CANCEL
    assert any("undo or redo" in text for _kind, text in op.reports)
    assert (_attr_bytes(ground.data), _attr_bytes(monkey.data)) == before
    assert "prt_bake" not in monkey.data
    assert all(not t.is_alive() for t in op._bake._pool._threads)


def test_a_file_saved_during_the_bake_holds_the_meshes_as_they_were(bpy_module, empty_scene, bake_ops, tmp_path):
    bpy = bpy_module
    ground, monkey = _monkey_on_ground(bpy)
    op, _ = _start(bake_ops, [ground, monkey])
    path = str(tmp_path / "during.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path, copy=True)
    assert _run_out(op) == {"FINISHED"}
    assert "prt_bake" in monkey.data
    bpy.ops.wm.open_mainfile(filepath=path)
    assert "prt_bake" not in bpy.data.meshes["Suzanne"]  # (not half-written: the bake writes at its end)
    assert not [a.name for a in bpy.data.meshes["Suzanne"].attributes if a.name.startswith("prt_")]


def test_a_file_loaded_during_the_bake_cancels_it(bpy_module, empty_scene, bake_ops):
    from prt_addon.blender.bake import reports, runner

    bpy = bpy_module
    ground, monkey = _monkey_on_ground(bpy, ground_cuts=30)
    op, _ = _start(bake_ops, [ground, monkey])
    runner._running.add(op)
    try:
        bpy.ops.wm.read_factory_settings(use_empty=True)  # (load_pre: running bakes are cancelled)
        assert op._bake._cancel
        assert _run_out(op) == {"CANCELLED"}
    finally:
        runner._running.discard(op)
    assert reports.last_report(bpy.context.scene)["message"] == runner.LOAD_CANCEL
    assert all(not t.is_alive() for t in op._bake._pool._threads)


def test_the_scene_switched_during_the_bake_gets_its_report_and_the_meshes_their_bake(
    bpy_module, empty_scene, bake_ops
):
    from prt_addon.blender.bake import reports

    bpy = bpy_module
    ground, monkey = _monkey_on_ground(bpy)
    op, _ = _start(bake_ops, [ground, monkey])
    other = bpy.data.scenes.new("Other")
    # The window shows the other scene from the next event on (headless: a context that says so).
    switched = types.SimpleNamespace(
        scene=other, window_manager=bpy.context.window_manager, workspace=None, screen=None
    )
    assert _run_out(op, switched) == {"FINISHED"}
    assert "prt_bake" in monkey.data and "prt_bake" in ground.data  # (the meshes the bake read)
    assert reports.last_report(other)["ok"]  # (the report where the user looks now)
    baked = reports.last_report(bpy.context.scene)  # (and in the scene that was baked)
    assert baked is not None and baked["ok"] and baked["seconds"] == reports.last_report(other)["seconds"]
    assert {o.name for o in other.objects} == set()  # (nothing written into the other scene)


def test_a_second_bake_while_one_runs_is_refused_and_the_first_goes_on(bpy_module, empty_scene, bake_ops):
    from prt_addon.blender.bake import reports, runner

    bpy = bpy_module
    ground, monkey = _monkey_on_ground(bpy)
    op, _ = _start(bake_ops, [ground, monkey])
    runner._running.add(op)
    try:
        bpy.ops.object.select_all(action="SELECT")
        with pytest.raises(RuntimeError, match="a bake is already running: wait for it to finish, or press Esc"):
            bpy.ops.prt.bake_transfer()
        assert "a bake is already running" in reports.last_report(empty_scene)["message"]
    finally:
        runner._running.discard(op)
    assert _run_out(op) == {"FINISHED"}
    assert reports.last_report(empty_scene)["ok"]


def test_the_bake_handlers_come_and_go_with_the_add_on(bpy_module, addon):
    from prt_addon.blender.bake import runner

    lists = [getattr(bpy_module.app.handlers, name) for name, _func in runner._HANDLERS]
    assert all(func in handlers for handlers, (_name, func) in zip(lists, runner._HANDLERS))
    addon.unregister()
    try:
        assert not any(func in handlers for handlers, (_name, func) in zip(lists, runner._HANDLERS))
    finally:
        addon.register()
    assert all(handlers.count(func) == 1 for handlers, (_name, func) in zip(lists, runner._HANDLERS))
