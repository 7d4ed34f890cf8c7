"""The test lanes: each test's markers come from its folder, shared fixtures from tests/helpers/.

tests/core/ is pure numpy and never imports bpy (a guard below fails a core test that does, and a
pure-lane run during whose collection bpy got imported); every other folder needs the bpy module
and adds its own lane marker. Run `-m "not blender"` for the pure lane, `-m "not cycles and not
gpu"` for the fast lane.
"""

import os
import pathlib
import sys

import pytest

pytest.register_assert_rewrite("helpers")

pytest_plugins = [
    "helpers.collection",
    "helpers.fixtures",
    "helpers.fixtures_bake",
    "helpers.fixtures_display",
    "helpers.fixtures_export",
    "helpers.fixtures_web",
]

# Folder under tests/ -> the markers its tests get. Tests outside every lane folder are taken to
# need bpy (tests/core/test_house_rules.py asks for each test module to be in a lane folder).
LANES = {
    "core": (),
    "blender": ("blender",),
    "cycles": ("blender", "cycles"),
    "gpu": ("blender", "gpu"),
    "browser": ("blender", "browser"),
}
TESTS = pathlib.Path(__file__).resolve().parent


def lane_of(path):
    """The lane folder of a test file ("core", "blender", ...), or None outside them."""
    try:
        folder = path.resolve().relative_to(TESTS).parts[0]
    except (ValueError, IndexError):
        return None
    return folder if folder in LANES else None


def pytest_itemcollected(item):
    for name in LANES.get(lane_of(item.path), ("blender",)):
        item.add_marker(name)


def pytest_collection_finish(session):
    """A run of core tests alone must not have imported bpy while collecting."""
    pure = bool(session.items) and all(lane_of(item.path) == "core" for item in session.items)
    session.config._prt_pure_run = pure
    if pure and "bpy" in sys.modules:
        raise pytest.UsageError(
            "bpy was imported while collecting a run of core tests only: a module imports bpy (or the "
            "Blender layer) at import time; do that inside a test or a fixture of a Blender lane"
        )


@pytest.fixture(autouse=True)
def _core_imports_no_bpy(request):
    """A core test that imports bpy (directly or through the Blender layer) fails here, in any run
    where bpy was not imported before it."""
    check = lane_of(request.node.path) == "core" and "bpy" not in sys.modules
    yield
    if check:
        assert "bpy" not in sys.modules, f"{request.node.nodeid} imported bpy: core tests run without Blender"


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
