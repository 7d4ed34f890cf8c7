"""The time-sliced modal runner of a bake: timer events advance the job, Esc cancels it.

A mixin for the bake operator: invoke() starts the job's steps on a window timer, each TIMER
event runs at most TIME_SLICE seconds of work, and every way out (finish, Esc, failure, the
add-on being disabled) removes the timer, ends the progress bar and closes the job's threads.
"""

import time

import bpy
from bpy.app.handlers import persistent

from .reports import _report_to_operator, _store_report
from .settings import BakeReport

TIME_SLICE = 0.1  # seconds of work per timer event of the modal bake


# Timer events closer than this to the end of the previous slice do no work: an Event does not
# say which timer fired, so other add-ons' timers would otherwise add slices and stall the UI.
TIMER_GAP = 0.015


_running = set()  # operators with a live timer, removed in unregister_extra()

OUTSIDE_CANCEL = "Bake cancelled (a file was loaded or the add-on disabled): nothing was changed"


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
        try:
            self._steps = job.steps()
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
            _store_report(context.scene, BakeReport(cancelled=True, message="Bake cancelled: nothing was changed"))
            self.report({"WARNING"}, "PRT: bake cancelled, nothing was changed")
            return {"CANCELLED"}
        if self._bake._cancel:  # cancelled from outside (a file loaded, the add-on disabled): write nothing
            self._cleanup(context)
            _store_report(context.scene, BakeReport(cancelled=True, message=OUTSIDE_CANCEL))
            self.report({"WARNING"}, f"PRT: {OUTSIDE_CANCEL}")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"} if event.type in _NAVIGATION else {"RUNNING_MODAL"}
        if time.perf_counter() - getattr(self, "_slice_end", float("-inf")) < TIMER_GAP:
            return {"RUNNING_MODAL"}  # (another timer right after our slice: let the UI run)
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
            _store_report(context.scene, report)
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
        _store_report(context.scene, BakeReport(message=f"Bake failed: {exc}"))
        self.report({"ERROR"}, f"PRT: bake failed, nothing was changed: {exc}")
        return {"CANCELLED"}


@persistent
def _on_load_pre(*_args):
    stop_running()  # (the meshes the bake read belong to the file being closed)


def register_extra():
    if _on_load_pre not in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.append(_on_load_pre)


def unregister_extra():
    while _on_load_pre in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.remove(_on_load_pre)
    stop_running()


def stop_running():
    """Stop a running modal bake (the add-on is being disabled, or another file loaded): cancel
    it, remove its timer, end the progress bar and status text, close the worker threads.
    Nothing is written."""
    for op in list(_running):
        _running.discard(op)
        for step in ("cancel", "timer", "steps", "close", "progress"):
            try:
                if step == "cancel":
                    op._bake.cancel()
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
