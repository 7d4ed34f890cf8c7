"""The time-sliced modal runner of a bake: timer events advance the job, Esc cancels it.

A mixin for the bake operator: invoke() starts the job's steps on a window timer, each TIMER
event runs at most TIME_SLICE seconds of work, and every way out (finish, Esc, failure, a baked
object deleted, undo or redo, a file loaded, the add-on being disabled) removes the timer, ends
the progress bar and closes the job's threads; docs/bake.md, "UI, cancel, undo", says what each does.
"""

import time

import bpy
from bpy.app.handlers import persistent

from .reports import _remember_unsaved, _report_to_operator, _scene_key, _store_report
from .settings import BakeReport

TIME_SLICE = 0.1  # seconds of work per timer event of the modal bake


# Timer events closer than this to the end of the previous slice do no work: an Event does not
# say which timer fired, so other add-ons' timers would otherwise add slices and stall the UI.
TIMER_GAP = 0.015


_running = set()  # operators with a live timer, removed in unregister_extra()

OUTSIDE_CANCEL = "Bake cancelled (the add-on was disabled): nothing was changed"
LOAD_CANCEL = "Bake cancelled (a file was loaded): nothing was changed"
UNDO_CANCEL = "Bake cancelled (undo or redo during the bake): nothing was changed, bake again"


_NAVIGATION = {
    "MIDDLEMOUSE",
    "WHEELUPMOUSE",
    "WHEELDOWNMOUSE",
    "MOUSEMOVE",
    "INBETWEEN_MOUSEMOVE",
    "TRACKPADPAN",
    "TRACKPADZOOM",
    "MOUSEROTATE",
    "NDOF_MOTION",
}


def watched(job):
    """(name, object pointer, mesh pointer) of each baked object: a reference to a deleted ID must
    not be touched, but its pointer can be looked for among bpy.data's."""
    return [(p.name, p.obj.as_pointer(), p.mesh.as_pointer()) for p in job.plans]


def deleted_name(watched_plans):
    """The name of a watched object whose object or mesh was deleted since, or None."""
    objects = {o.as_pointer() for o in bpy.data.objects}
    meshes = {m.as_pointer() for m in bpy.data.meshes}
    for name, obj, mesh in watched_plans:
        if obj not in objects or mesh not in meshes:
            return name
    return None


class TimeSlicedRunner:
    """Modal half of the bake operator; the operator provides `_job(context)` (a BakeJob or
    None after reporting why) and `execute(context)` (the bake at once, without a window)."""

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        job = self._job(context)
        if job is None:
            return {"CANCELLED"}
        self._bake = job
        scene = getattr(context, "scene", None)
        self._scene_key = _scene_key(scene) if scene is not None else None
        try:
            self._steps = job.steps()
            self._watched = watched(job)
            wm = context.window_manager
            self._timer = wm.event_timer_add(0.02, window=context.window)
            wm.progress_begin(0, 100)
            wm.modal_handler_add(self)
            _running.add(self)
        except BaseException:
            # The job's first slices are already running: stop them (nothing was written).
            try:
                self._cleanup(context)
            finally:
                job.close()
            raise
        return {"RUNNING_MODAL"}

    def _store(self, context, report):
        """The report goes to the scene the window shows and, when the user switched scenes during
        the bake, to the scene that was baked too (looked up by its key: it may have been deleted)."""
        _store_report(context.scene, report)
        baked = getattr(self, "_scene_key", None)
        for scene in bpy.data.scenes:
            if _scene_key(scene) == baked and scene != context.scene:
                _store_report(scene, report)

    def _cleanup(self, context):
        wm = context.window_manager
        if getattr(self, "_timer", None) is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        if getattr(self, "_steps", None) is not None:
            self._steps.close()
        if getattr(self, "_bake", None) is not None:
            self._bake.close()
        _running.discard(self)
        for area in context.screen.areas if context.screen else ():
            area.tag_redraw()

    def modal(self, context, event):
        if event.type == "ESC":
            self._bake.cancel()
            self._cleanup(context)
            self._store(context, BakeReport(cancelled=True, message="Bake cancelled: nothing was changed"))
            self.report({"WARNING"}, "PRT: bake cancelled, nothing was changed")
            return {"CANCELLED"}
        if self._bake._cancel:  # cancelled from outside (undo, a file loaded, the add-on disabled): write nothing
            message = getattr(self, "_stopped", None) or OUTSIDE_CANCEL
            self._cleanup(context)
            self._store(context, BakeReport(cancelled=True, message=message))
            self.report({"WARNING"}, f"PRT: {message}")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"} if event.type in _NAVIGATION else {"RUNNING_MODAL"}
        if time.perf_counter() - getattr(self, "_slice_end", float("-inf")) < TIMER_GAP:
            return {"RUNNING_MODAL"}  # (another timer right after our slice: let the UI run)
        if getattr(self, "_watched", None) is None:
            self._watched = watched(self._bake)
        deleted = deleted_name(self._watched)
        if deleted is not None:
            self._bake.cancel()
            return self._fail(context, f"'{deleted}' was deleted during the bake")
        deadline = time.perf_counter() + TIME_SLICE
        try:
            while True:  # at least one chunk per timer event
                fraction, text = next(self._steps)
                if time.perf_counter() >= deadline:
                    break
        except StopIteration:
            try:
                report = self._bake.finish()
            except Exception as exc:
                return self._fail(context, exc)
            self._cleanup(context)
            self._store(context, report)
            _report_to_operator(self, report)
            return {"FINISHED"}
        except Exception as exc:
            return self._fail(context, exc)
        context.window_manager.progress_update(100.0 * fraction)
        if context.workspace is not None:
            context.workspace.status_text_set(f"PRT: {text} (Esc to cancel)")
        self._slice_end = time.perf_counter()
        return {"RUNNING_MODAL"}

    def _fail(self, context, exc):
        self._cleanup(context)
        self._store(context, BakeReport(message=f"Bake failed: {exc}"))
        self.report({"ERROR"}, f"PRT: bake failed, nothing was changed: {exc}")
        return {"CANCELLED"}


@persistent
def _on_load_pre(*_args):
    stop_running(LOAD_CANCEL)  # (the meshes the bake read belong to the file being closed)


@persistent
def _on_undo_pre(*_args):
    # Undo reads the file's state back: the meshes the bake would write may be other data by then.
    stop_running(UNDO_CANCEL)


_HANDLERS = (("load_pre", _on_load_pre), ("undo_pre", _on_undo_pre), ("redo_pre", _on_undo_pre))


def register_extra():
    for name, func in _HANDLERS:
        handlers = getattr(bpy.app.handlers, name)
        if func not in handlers:
            handlers.append(func)


def unregister_extra():
    for name, func in _HANDLERS:
        handlers = getattr(bpy.app.handlers, name)
        while func in handlers:
            handlers.remove(func)
    stop_running(OUTSIDE_CANCEL)


def stop_running(message=OUTSIDE_CANCEL):
    """Stop a running modal bake (undo or redo, another file loaded, the add-on disabled):
    cancel it, remove its timer, end the progress bar and status text, close the worker threads;
    its next event reports `message` to the caller, and the panel shows it at once (the next event
    may be long in coming: the timer is gone). Nothing is written."""
    for op in list(_running):
        _running.discard(op)
        op._stopped = message
        for step in ("cancel", "report", "timer", "steps", "close", "progress"):
            try:
                if step == "cancel":
                    op._bake.cancel()
                elif step == "report" and getattr(op, "_scene_key", None) is not None:
                    _remember_unsaved(op._scene_key, BakeReport(cancelled=True, message=message))
                elif step == "timer" and op._timer is not None:
                    bpy.context.window_manager.event_timer_remove(op._timer)
                    op._timer = None
                elif step == "steps":
                    op._steps.close()
                elif step == "close":
                    op._bake.close()
                elif step == "progress":
                    wm = bpy.context.window_manager
                    if wm is not None:
                        wm.progress_end()
                    workspace = bpy.context.workspace
                    if workspace is not None:
                        workspace.status_text_set(None)
            except (ReferenceError, AttributeError, RuntimeError, TypeError, ValueError):
                pass
