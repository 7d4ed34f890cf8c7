"""The real-window check's faults during a modal bake: a second Bake, Ctrl+Z pressed, the file
saved, the scene switched, undo from a script, a baked object deleted; what each bake ends with."""

import os
import time

import bpy

SAMPLES = 1024  # a bake of a few seconds, so that the fault lands while it runs (+64 per fault:
# each bake that finishes then writes other values than the one before)
FAULTS = ("second", "ctrl_z", "save", "scene", "undo", "delete")  # (delete last: Ground is gone after it)
WAIT_SECONDS = 60


def _apply(fault, tools, out):
    """Does `fault` to the running bake, as a user or a script would; what it returned goes in out."""
    window = bpy.context.window_manager.windows[0]
    with bpy.context.temp_override(**tools.window_context()):
        if fault == "second":  # (an operator that reports an error raises it to a script)
            try:
                out["second_invoke"] = tools.start_bake()
            except RuntimeError as e:
                out["second_invoke"] = str(e)
        elif fault == "ctrl_z":  # the key, in the window: the bake's modal handler sees it first
            window.event_simulate(type="Z", value="PRESS", ctrl=True)
            window.event_simulate(type="Z", value="RELEASE", ctrl=True)
        elif fault == "save":
            out["save"] = list(bpy.ops.wm.save_mainfile())
            out["saved_at"] = os.path.getmtime(bpy.data.filepath)
        elif fault == "scene":
            out["baked_scene"] = bpy.context.scene.name
            window.scene = bpy.data.scenes.new("Other")
        elif fault == "undo":
            out["undo"] = list(bpy.ops.ed.undo())
            out["before"] = tools.prt_bytes()  # (the undone state: the bake must leave it as it is)
        elif fault == "delete":
            bpy.data.objects.remove(bpy.data.objects["Ground"])


def step(result, state, tools):
    """One tick of the faults phase: -> seconds until the next, or None when every fault is done.
    tools: the check's start_bake, running_job, prt_bytes, bake_threads, window_context, mod."""
    faults = result.setdefault("faults", {})
    fault = next((f for f in FAULTS if "ended" not in faults.get(f, {})), None)
    if fault is None:
        return None
    out = faults.setdefault(fault, {})
    job = tools.running_job()
    if "invoke" not in out:
        out["samples"] = bpy.context.scene.prt_bake.samples = SAMPLES + 64 * FAULTS.index(fault)
        state["t"] = time.perf_counter()  # (the check's time limit is per fault)
        out["before"] = tools.prt_bytes()
        out["invoke"] = tools.start_bake()
        out["t"] = time.perf_counter()
        return 0.05
    if "applied" not in out:
        if job is not None and job.fraction < 0.05 and time.perf_counter() - out["t"] < WAIT_SECONDS:
            return 0.05
        out["fraction_at_fault"] = job.fraction if job is not None else None
        _apply(fault, tools, out)
        out["applied"] = time.perf_counter()
        return 0.05
    if job is not None and time.perf_counter() - out["applied"] < WAIT_SECONDS:
        return 0.05
    out["ended"] = time.perf_counter() - out["applied"]
    out["still_running"] = job is not None
    if fault == "scene":
        baked = bpy.data.scenes[out["baked_scene"]]
        out["report"] = tools.mod("blender.bake.reports").last_report(baked)
        bpy.context.window_manager.windows[0].scene = baked
    else:
        out["report"] = tools.mod("blender.bake.reports").last_report(bpy.context.scene)
    names = ("Suzanne",) if fault == "delete" else ("Suzanne", "Ground")
    out["after"] = tools.prt_bytes(names)
    out["unchanged"] = out["after"] == {name: out["before"][name] for name in names}
    out["threads"] = tools.bake_threads()
    for key in ("before", "after"):
        out.pop(key)  # (digests of every attribute: the verdict needs only whether they changed)
    return 0.3


def checks(result):
    """The faults' checks: name -> passed."""
    f = result.get("faults", {})

    def ended(fault, ok, changed, words=""):
        out = f.get(fault, {})
        report = out.get("report") or {}
        return (
            out.get("invoke") == ["RUNNING_MODAL"]
            and out.get("still_running") is False
            and out.get("threads") == []
            and bool(report.get("ok")) == ok
            and out.get("unchanged") is (not changed)
            and words in report.get("message", "")
            and (not ok or report.get("samples") == out.get("samples"))  # (this bake's report)
        )

    second = "a bake is already running" in str(f.get("second", {}).get("second_invoke"))
    return {
        "a second Bake while one runs is refused, the first finishes": second and ended("second", True, True),
        "Ctrl+Z in the window during a bake is ignored, the bake finishes": ended("ctrl_z", True, True),
        "the file saved during a bake: the bake finishes": ended("save", True, True)
        and f["save"].get("save") == ["FINISHED"],
        "the scene switched during a bake: the bake finishes with its report": ended("scene", True, True),
        "undo from a script during a bake stops it, nothing changed": ended("undo", False, False, "undo"),
        "a baked object deleted during a bake stops it, the others unchanged": ended(
            "delete", False, False, "'Ground' was deleted"
        ),
    }
