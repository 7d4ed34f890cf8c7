"""Shared fixtures. Core tests need only numpy; Blender-layer tests use the `bpy` module."""

import os
import threading
import time

import numpy as np
import pytest


@pytest.fixture(scope="session")
def bpy_module():
    import bpy

    return bpy


@pytest.fixture(scope="session")
def addon(bpy_module):
    """The add-on registered once for the session (unregistered at the end)."""
    import prt_addon

    prt_addon.register()
    yield prt_addon
    prt_addon.unregister()


@pytest.fixture
def empty_scene(bpy_module, addon):
    """Factory settings with no objects, no camera and no world; the add-on stays registered."""
    bpy_module.ops.wm.read_factory_settings(use_empty=True)
    # read_factory_settings unregisters nothing of ours, but make sure the scene property exists.
    assert hasattr(bpy_module.types.Scene, "prt")
    return bpy_module.context.scene


@pytest.fixture(scope="module")
def gpu_ready(bpy_module, addon):
    """Initialise the GPU once for the module (a tiny Workbench render), before large meshes."""
    from prt_addon.blender.display import offscreen

    assert offscreen.ensure_gpu()
    return True


def cycles_vertex_bake(bpy, scene, objects, samples, passes=("DIRECT",), bounces=None):
    """{object name: (V, 3)} E/pi per vertex (white albedo) from Cycles' DIFFUSE bake of the
    objects alone, with `passes` and, when given, `bounces` diffuse bounces; the temporary colour
    attribute is removed again."""
    bpy.ops.object.select_all(action="DESELECT")
    for obj in objects:
        colours = obj.data.color_attributes
        colours.active_color = colours.new("cycles", "FLOAT_COLOR", "POINT")
        obj.select_set(True)
    bpy.context.view_layer.objects.active = objects[0]
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    if bounces is not None:
        scene.cycles.diffuse_bounces = bounces
        scene.cycles.max_bounces = bounces + 4
        scene.cycles.glossy_bounces = scene.cycles.transmission_bounces = 0
    bpy.ops.object.bake(type="DIFFUSE", pass_filter=set(passes), target="VERTEX_COLORS", use_clear=True)
    out = {}
    for obj in objects:
        colours = obj.data.color_attributes
        values = np.empty(len(obj.data.vertices) * 4, np.float32)
        colours["cycles"].data.foreach_get("color", values)
        out[obj.name] = values.reshape(-1, 4)[:, :3].astype(np.float64)
        colours.remove(colours["cycles"])
    return out


def bundled_hdri_path(name="forest"):
    """Path of one of Blender's bundled studio-light HDRIs (1024x512 EXR, CC0)."""
    import bpy

    folder = bpy.utils.system_resource("DATAFILES", path="studiolights/world")
    path = os.path.join(folder, f"{name}.exr")
    assert os.path.isfile(path), path
    return path


def random_directions(count, seed):
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(count, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def other_threads_cpu_ticks():
    """CPU clock ticks (user + system) used so far by this process's threads other than the
    calling one, from /proc/self/task (Linux)."""
    me = threading.get_native_id()
    total = 0
    for task in os.listdir("/proc/self/task"):
        if int(task) == me:
            continue
        try:
            with open(f"/proc/self/task/{task}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except OSError:  # the thread ended meanwhile
            continue
        total += int(fields[11]) + int(fields[12])  # utime, stime (fields 14 and 15 of stat)
    return total


def ticks_of_other_threads_after(call, window=0.15):
    """Clock ticks (1/100 s) that other threads of this process use in the `window` seconds
    after call() returns, while this thread sleeps: about 100 * window when a BLAS worker spins,
    0 when nothing else runs. Counted per thread, so other processes loading the machine do not
    blur it as a wall-clock measure would."""
    time.sleep(0.3)  # let any worker from earlier calls go to sleep
    call()
    before = other_threads_cpu_ticks()
    time.sleep(window)
    return other_threads_cpu_ticks() - before


def fake_event(event_type, value="PRESS"):
    """A stand-in for bpy.types.Event, which Python cannot create: it has exactly the attributes
    of a real Event (read from its RNA definition), so code that reads anything else fails here
    as it does in Blender. An earlier stand-in had an invented `timer` attribute, which hid a
    modal() that failed on the first timer event of every interactive bake."""
    import types

    import bpy

    names = [n for n in bpy.types.Event.bl_rna.properties.keys() if n != "rna_type"]
    event = types.SimpleNamespace(**{n: None for n in names})
    event.type, event.value = event_type, value
    return event


class ModalStandIn:
    """Stands in for a PRT_OT_bake_transfer instance driven through modal() (bpy as a module has
    no window, so invoke() cannot start a real modal handler; Blender creates operator instances
    only through bpy.ops). reports collects (set of kinds, message)."""

    def __init__(self, bake_ops, job):
        cls = bake_ops.PRT_OT_bake_transfer
        self._bake, self._steps, self._timer, self.reports = job, job.steps(), None, []
        self.report = lambda kind, msg: self.reports.append((set(kind), msg))
        self._cleanup = lambda ctx: cls._cleanup(self, ctx)
        self._fail = lambda ctx, exc: cls._fail(self, ctx, exc)
        self.modal = lambda ctx, event: cls.modal(self, ctx, event)


def pytest_unconfigure(config):
    """bpy 4.2 (the module, not Blender) crashes at interpreter exit once io_scene_gltf2 has
    exported anything: its SpaceType destructors run after Python is finalised and call
    PyGILState_Ensure (gdb: bpy_class_free <- ~SpaceType <- exit handlers), even for a default
    cube exported by a script that does nothing else. 4.3 and later exit cleanly. Leave before
    those destructors on 4.2, with pytest's own exit status, so that a passing run reads as one."""
    import sys

    bpy = sys.modules.get("bpy")
    if bpy is None or tuple(bpy.app.version[:2]) >= (4, 3) or "io_scene_gltf2" not in sys.modules:
        return
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(int(getattr(config, "_prt_exit_status", 0)))


def pytest_sessionfinish(session, exitstatus):
    session.config._prt_exit_status = int(exitstatus)
