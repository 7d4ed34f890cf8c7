"""The fixtures every lane outside core shares: bpy, the add-on registered once, an empty scene, the GPU (loaded by tests/conftest.py through pytest_plugins)."""

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
