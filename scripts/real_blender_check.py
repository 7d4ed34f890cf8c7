"""Run by a real Blender with a window (real_blender_check.sh): blender --factory-startup --enable-event-simulate
--python real_blender_check.py -- ZIP RESULT_JSON. Installs the extension zip as a user would, checks which Embree the
shared-buffer path binds to (and that it answers as embreex's copy does), then drives the real modal bake through
Blender's event loop: a bake, one undo and one redo, the display with its light directions and colours
(real_blender_colour.py), a long bake cancelled by a simulated Esc while this script's timers sample its progress.
Writes a verdict per check to RESULT_JSON."""

import json
import os
import sys
import threading
import time
import traceback
import types

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import real_blender_colour
import real_blender_embree
import real_blender_faults
import real_blender_shots

# Every check, in order; real_blender_check.sh reads it from the source (all fail without a result or set-up).
CHECKS = (
    "extension installed and enabled",
    "embreex imports",
    "shared buffers used, same answers as embreex's copy",
    "invoke() starts a modal bake",
    "the modal bake finishes with Embree",
    "no worker thread left after the bake",
    "one undo removes the whole bake",
    "redo brings it back unchanged",
    "the world projects and the display draws both baked objects",
    "the sidebar's PRT tab draws",
    "the overlay shows the view transform as Blender applies it",
    "the light directions draw in the viewport and turn with the lighting",
    "the viewport draws the turned lighting within 2 s (Suzanne changes on screen)",
    "progress advances between timer events (the UI runs)",
    "Esc cancels within 1 s",
    "a cancelled bake leaves the attributes as they were",
    "no worker thread left after Esc",
    "a second Bake while one runs is refused, the first finishes",
    "Ctrl+Z in the window during a bake is ignored, the bake finishes",
    "the file saved during a bake: the bake finishes",
    "the scene switched during a bake: the bake finishes with its report",
    "undo from a script during a bake stops it, nothing changed",
    "a baked object deleted during a bake stops it, the others unchanged",
    "no exception",
    "no Python traceback in Blender's output",
)

argv = sys.argv[sys.argv.index("--") + 1 :]
ZIP, RESULT = argv[0], argv[1]
MODULE = "bl_ext.user_default.prt_lighting"
result = {"blender": bpy.app.version_string, "python": sys.version.split()[0], "log": []}


class SetupError(Exception):
    """The extension could not be installed and enabled: every check fails with this message."""


def log(*args):
    line = " ".join(str(a) for a in args)
    result["log"].append(line)
    print("CHECK:", line, flush=True)


def window_context():
    window = bpy.context.window_manager.windows[0]
    area = max((a for a in window.screen.areas if a.type == "VIEW_3D"), key=lambda a: a.width * a.height)
    region = [r for r in area.regions if r.type == "WINDOW"][0]
    return {"window": window, "area": area, "region": region, "screen": window.screen}


def mod(name):
    return sys.modules[f"{MODULE}.prt_addon.{name}"]


def prt_bytes(mesh_names=("Suzanne", "Ground")):
    """Every prt_* attribute (a digest of its bytes) and the bake record of each mesh."""
    return {name: mesh_prt_bytes(name) for name in mesh_names}


def mesh_prt_bytes(mesh_name):
    import numpy as np

    mesh = bpy.data.meshes[mesh_name]
    out = {}
    for attr in mesh.attributes:
        if attr.name.startswith("prt_t"):
            buf = np.empty(len(attr.data) * 4, np.float32)
            attr.data.foreach_get("color", buf)
            out[attr.name] = buf.tobytes().hex()[:64] + f"..{len(buf)}:{hash(buf.tobytes())}"
    record = mesh.get("prt_bake")
    out["record"] = json.dumps(record.to_dict(), sort_keys=True) if record is not None else None
    return out


def light_directions():
    return [light.direction.tolist() for light in mod("blender.scene.lighting").world_lights(bpy.context.scene)]


def bake_threads():
    return sorted(t.name for t in threading.enumerate() if t.name.startswith("prt-bake"))


def install():
    """Install the zip and enable the extension as a user would; SetupError when that fails."""
    import importlib

    try:
        import numpy  # noqa: F401
    except ImportError as e:
        raise SetupError(f"Blender's Python has no numpy: {e}") from e
    try:
        install_files = bpy.ops.extensions.package_install_files
        result["install"] = list(install_files(filepath=ZIP, repo="user_default", enable_on_install=True))
    except Exception as e:
        raise SetupError(f"installing {os.path.basename(ZIP)} failed: {e}".strip()) from e
    if result["install"] != ["FINISHED"]:
        raise SetupError(f"installing {os.path.basename(ZIP)} returned {result['install']}")
    if MODULE not in bpy.context.preferences.addons:
        import addon_utils  # enabling once more, only to catch the error that the install's enabling printed

        errors = []
        addon_utils.enable(MODULE, default_set=True, handle_error=errors.append)
        why = f"{type(errors[0]).__name__}: {errors[0]}" if errors else f"{MODULE} is not in the add-ons"
        raise SetupError(f"package_install_files returned FINISHED, but the extension did not enable ({why})")
    try:
        importlib.import_module(f"{MODULE}.prt_addon.core.trace.raytrace")
    except Exception as e:
        raise SetupError(f"the enabled extension does not import: {type(e).__name__}: {e}") from e
    result["enabled"] = True


def setup():
    install()
    real_blender_embree.check(result, mod("core.trace.raytrace"), mod("core.trace.embree_buffers"))
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=60, y_subdivisions=60, size=8)
    bpy.context.object.name = bpy.context.object.data.name = "Ground"
    bpy.ops.mesh.primitive_monkey_add(location=(0, 0, 1))
    monkey = bpy.context.object
    monkey.modifiers.new("s", "SUBSURF").levels = 2
    bpy.ops.object.modifier_apply(modifier="s")
    monkey.data.shade_smooth()
    bpy.ops.object.select_all(action="SELECT")
    scene = bpy.context.scene
    scene.prt_bake.order, scene.prt_bake.samples = 4, 256
    with bpy.context.temp_override(**window_context()):
        bpy.ops.ed.undo_push(message="before PRT bake")
    result["before"] = prt_bytes()


state = {"phase": "splash", "t": None, "fractions": []}


def start_bake():
    with bpy.context.temp_override(**window_context()):
        return list(bpy.ops.prt.bake_transfer("INVOKE_DEFAULT"))


def running_job():
    ops = list(mod("blender.bake.runner")._running)
    return ops[0]._bake if ops else None


def tick():
    try:
        return step()
    except SetupError as e:
        result["setup_error"] = str(e)
    except Exception:
        result["exception"] = traceback.format_exc()
    finish()
    return None


PHASE_SECONDS = 120  # a phase that takes longer than this has hung: report it and quit


def step():
    phase = state["phase"]
    if state["t"] is not None and time.perf_counter() - state["t"] > PHASE_SECONDS:
        result["exception"] = f"timed out in phase '{phase}' after {PHASE_SECONDS} s"
        finish()
        return None
    if phase == "splash":
        window = bpy.context.window_manager.windows[0]
        window.event_simulate(type="ESC", value="PRESS")  # closes the splash screen
        window.event_simulate(type="ESC", value="RELEASE")
        state["phase"] = "setup"
        return 0.5
    if phase == "setup":
        setup()
        state["phase"] = "bake"
        state["invoke"] = start_bake()
        result["invoke"] = state["invoke"]
        result["threads_during_bake"] = bake_threads()
        state["t"] = time.perf_counter()
        return 0.02
    bake_reports = mod("blender.bake.reports")
    result["markers_drawn"] = state.get("markers", [])  # (phase, lights drawn) per viewport redraw
    if phase == "bake":
        job = running_job()
        if job is not None:
            state["fractions"].append(round(job.fraction, 3))
            return 0.02
        result["bake_seconds"] = time.perf_counter() - state["t"]
        result["progress_samples"] = state["fractions"]
        result["report"] = bake_reports.last_report(bpy.context.scene)
        result["after_bake"] = prt_bytes()
        result["threads_after_bake"] = bake_threads()
        with bpy.context.temp_override(**window_context()):
            result["undo"] = list(bpy.ops.ed.undo())
        result["after_undo"] = prt_bytes()
        with bpy.context.temp_override(**window_context()):
            result["redo"] = list(bpy.ops.ed.redo())
        result["after_redo"] = prt_bytes()
        # The live display in this window: project the world, show the display, turn the light.
        world = bpy.data.worlds.new("PRT World")
        if world.node_tree is None:
            world.use_nodes = True
        bpy.context.scene.world = world
        env = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
        folder = bpy.utils.system_resource("DATAFILES", path="studiolights/world")
        env.image = bpy.data.images.load(os.path.join(folder, "forest.exr"))
        world.node_tree.links.new(env.outputs["Color"], world.node_tree.nodes["Background"].inputs["Color"])
        with bpy.context.temp_override(**window_context()):
            result["project"] = list(bpy.ops.prt.project_world())
        bpy.context.scene.prt.show_display = True
        bpy.context.scene.prt_display.show_light_directions = True  # forest.exr: 3 split lights
        markers, drawn = mod("blender.display.light_markers"), state.setdefault("markers", [])
        draw_markers = markers.draw_markers  # count what the viewport's handler draws, per phase
        markers.draw_markers = lambda *a, **k: drawn.append((state["phase"], draw_markers(*a, **k), time.time()))
        area = window_context()["area"]
        area.spaces.active.show_region_ui = True  # the sidebar, on its "PRT" tab: draws our panels
        area.tag_redraw()
        state.update(phase="sidebar", t=time.perf_counter(), tab_tries=0)
        return 0.3
    if phase == "sidebar":
        # active_panel_category is read-only in 4.3: click down the tab strip's right edge, 8 px at a time, to PRT.
        area = window_context()["area"]
        sidebar = [r for r in area.regions if r.type == "UI"][0]
        if sidebar.active_panel_category != "PRT" and state["tab_tries"] < 60:
            window = bpy.context.window_manager.windows[0]
            x = sidebar.x + sidebar.width - 8
            y = sidebar.y + sidebar.height - 10 - 8 * state["tab_tries"]
            window.event_simulate(type="MOUSEMOVE", value="NOTHING", x=x, y=y)
            window.event_simulate(type="LEFTMOUSE", value="PRESS", x=x, y=y)
            window.event_simulate(type="LEFTMOUSE", value="RELEASE", x=x, y=y)
            state["tab_tries"] += 1
            return 0.3  # (simulated events are handled later: wait before looking again)
        result["sidebar_tab"] = sidebar.active_panel_category
        result["display_on_at"] = time.time()
        state["phase"] = "display"
        state["t"] = time.perf_counter()
        return 1.5
    if phase == "display":
        display_draw = mod("blender.display.draw")
        gpu_cache = mod("blender.display.gpu_cache")
        result["display_handler"] = display_draw.draw_handle() is not None
        result["display_meshes_drawn"] = len(gpu_cache._mesh_cache)
        result["light_directions"] = [light_directions()]
        with bpy.context.temp_override(**window_context()):
            result["rotate"] = list(bpy.ops.prt.set_light_rotation(rotation=(0.0, 0.0, 2.0)))
        result["rotated_at"] = time.time()
        result["light_directions"].append(light_directions())
        result["suzanne_box"] = real_blender_shots.screen_box(bpy.data.objects["Suzanne"], window_context())
        state.update(phase="turned", t=time.perf_counter())
        return 0.05
    if phase == "turned":
        wait = real_blender_shots.wait_turn(result, state["markers"])
        if wait:
            return wait
        real_blender_colour.prepare(window_context())  # (no outline over the compared pixels)
        state.update(phase="colour", t=time.perf_counter())
        return 0.5
    if phase == "colour":
        wait = real_blender_colour.step(result, mod, window_context())  # (over several ticks)
        if wait:
            return wait
        phase = "long"
    if phase == "long":
        # A long bake, cancelled with Esc once it is under way.
        bpy.context.scene.prt_bake.samples = 8192
        state["phase"] = "cancel"
        state["fractions"] = []
        result["invoke_long"] = start_bake()
        state["t"] = time.perf_counter()
        return 0.02
    if phase == "cancel":
        job = running_job()
        if job is not None and not state.get("esc_sent"):
            state["fractions"].append(round(job.fraction, 3))
            state["ticks"] = state.get("ticks", 0) + 1
            if job.fraction > 0.35:
                window = bpy.context.window_manager.windows[0]
                window.event_simulate(type="ESC", value="PRESS")
                window.event_simulate(type="ESC", value="RELEASE")
                state["esc_sent"] = time.perf_counter()
                result["fraction_at_esc"] = job.fraction
                result["script_timer_ticks_during_long_bake"] = state["ticks"]
                result["progress_samples_long_bake"] = state["fractions"]
            return 0.02
        if job is not None:
            if time.perf_counter() - state["esc_sent"] > 10:
                result["esc_ignored"] = True
                finish()
                return None
            return 0.02
        time.sleep(0.2)
        result["cancel_seconds_after_esc"] = time.perf_counter() - state["esc_sent"]
        result["cancel_report"] = bake_reports.last_report(bpy.context.scene)
        result["after_cancel"] = prt_bytes()
        result["threads_after_cancel"] = bake_threads()
        state["phase"] = "faults"
        return 0.3
    if phase == "faults":  # a second Bake, Ctrl+Z, save, another scene, undo, deletion: each during a bake
        tools = (start_bake, running_job, prt_bytes, bake_threads, window_context, mod)
        wait = real_blender_faults.step(result, state, types.SimpleNamespace(**{f.__name__: f for f in tools}))
        if wait:
            return wait
        finish()
    return None


def same(a, b):
    """a == b, where both were recorded (a phase that never ran recorded neither)."""
    return a is not None and b is not None and a == b


def verdict():
    r = result
    bake_attrs = {k for mesh in r.get("after_bake", {}).values() for k in mesh if k != "record"}
    report = r.get("report", {})  # order 4: 4 attributes of direct transfer, 4 per bounced channel, 4 back
    bounced_blocks = report.get("bounce_channels", 0) if report.get("bounces") else 0
    backs_baked = int(any(json.loads(m["record"] or "{}").get("back", 0) for m in r.get("after_bake", {}).values()))
    long_samples = r.get("progress_samples_long_bake", [])
    drawn = {phase for phase, lights, _ in r.get("markers_drawn", []) if lights}  # phases with markers drawn
    markers_turn = bool(drawn & {"sidebar", "display"} and drawn & {"turned", "long", "cancel"})  # before, after
    markers_turn = markers_turn and len(set(map(str, r.get("light_directions", [])))) == 2
    redraw, shots = r.get("turn_redraw_seconds"), real_blender_shots
    turn_drawn = redraw is not None and redraw <= shots.REDRAW_SECONDS
    turn_drawn = turn_drawn and r.get("turn_viewport_change", 0) >= shots.MIN_CHANGE
    checks = {
        "extension installed and enabled": r.get("install") == ["FINISHED"] and bool(r.get("enabled")),
        "embreex imports": bool(r.get("embree_available")),
        "shared buffers used, same answers as embreex's copy": r.get("geometry") == ["SHARED", "COPIED"]
        and bool(r.get("shared_vs_copied_equal")),
        "invoke() starts a modal bake": r.get("invoke") == ["RUNNING_MODAL"],
        "the modal bake finishes with Embree": bool(r.get("report", {}).get("ok"))
        and r.get("report", {}).get("backend") == "EMBREE"
        and len(bake_attrs) == 4 * (1 + bounced_blocks + backs_baked)
        and bool(r.get("after_bake"))
        and all(mesh["record"] is not None for mesh in r["after_bake"].values()),
        "no worker thread left after the bake": r.get("threads_after_bake") == [],
        "one undo removes the whole bake": same(r.get("after_undo"), r.get("before"))
        and same(r.get("undo"), ["FINISHED"]),
        "redo brings it back unchanged": same(r.get("after_redo"), r.get("after_bake"))
        and same(r.get("redo"), ["FINISHED"]),
        "the world projects and the display draws both baked objects": r.get("project") == ["FINISHED"]
        and bool(r.get("display_handler"))
        and r.get("display_meshes_drawn") == 2
        and r.get("rotate") == ["FINISHED"],
        "the sidebar's PRT tab draws": r.get("sidebar_tab") == "PRT",
        real_blender_colour.CHECK: real_blender_colour.passed(r),
        "the light directions draw in the viewport and turn with the lighting": markers_turn,
        "the viewport draws the turned lighting within 2 s (Suzanne changes on screen)": turn_drawn,
        "progress advances between timer events (the UI runs)": len(long_samples) >= 3
        and all(a < b for a, b in zip(long_samples, long_samples[1:])),
        "Esc cancels within 1 s": bool(r.get("cancel_report", {}).get("cancelled"))
        and r.get("cancel_seconds_after_esc", 99) < 1.0,
        "a cancelled bake leaves the attributes as they were": same(r.get("after_cancel"), r.get("after_bake")),
        "no worker thread left after Esc": r.get("threads_after_cancel") == [],
        **real_blender_faults.checks(r),
        "no exception": "exception" not in r and "setup_error" not in r,
    }
    assert list(checks) == list(CHECKS[:-1]), "verdict() and CHECKS name different checks"
    if "setup_error" in r:  # nothing was checked: no check passes, however its test reads
        checks = dict.fromkeys(checks, False)
    r["checks"] = checks
    r["passed"] = all(checks.values())


def finish():
    real_blender_shots.compare(result, os.path.join(os.path.dirname(RESULT), "shots"))
    verdict()
    with open(RESULT, "w") as f:
        json.dump(result, f, indent=1)
    log("done")
    bpy.ops.wm.quit_blender()


bpy.app.timers.register(tick, first_interval=1.0)
