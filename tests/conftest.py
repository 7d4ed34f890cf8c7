"""Shared fixtures. Core tests need only numpy; Blender-layer tests use the `bpy` module."""

import os
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


def process_cpu_per_wall_second(seconds=0.06):
    """CPU seconds of this whole process per wall second while this thread runs small numpy
    operations: about 1 with one busy thread, about 2 when another thread spins meanwhile."""
    data = np.random.default_rng(0).random(50_000)
    w0, c0 = time.perf_counter(), time.process_time()
    while time.perf_counter() - w0 < seconds:
        np.sin(data)
    return (time.process_time() - c0) / (time.perf_counter() - w0)


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
