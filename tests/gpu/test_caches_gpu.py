"""File load empties every cache that the display (GPU) and the bake filled."""

import importlib
import pkgutil

import numpy as np
from helpers.caches import _ground_and_box

# Module-level containers that are tables or bookkeeping, not caches of scene data.
NOT_CACHES = {
    ("prt_addon.blender.registration", "_registered"),  # what register() registered, for unregister()
    ("prt_addon.blender.bake.runner", "_running"),  # live modal bakes, stopped in unregister()
    ("prt_addon.blender.bake.reports", "_unsaved_reports"),  # the last refused bake's report
    ("prt_addon.blender.caches", "_clears"),
    ("prt_addon.blender.caches", "_geometry"),
    ("prt_addon.blender.display.shadows", "_generation"),  # a counter, not data
}


def _blender_modules():
    import prt_addon.blender as layer

    for info in pkgutil.walk_packages(layer.__path__, "prt_addon.blender."):
        yield importlib.import_module(info.name)


def _filled_containers():
    """(module, name, size) of every non-empty module-level dict (None values aside), list or set of the layer."""
    out = []
    for module in _blender_modules():
        for name, value in vars(module).items():
            if (
                (module.__name__, name) in NOT_CACHES
                or name.isupper()
                or not name.startswith("_")
                or name.startswith("__")
            ):
                continue
            held = [v for v in value.values() if v is not None] if isinstance(value, dict) else value
            if isinstance(value, dict | list | set) and len(held):
                out.append((module.__name__, name, len(held)))
    return out


def test_file_load_empties_every_cache_the_display_and_the_bake_filled(bpy_module, empty_scene, gpu_ready):
    """After drawing, shading and overriding, loading a file leaves no module-level container of
    the Blender layer holding scene data (a new cache that no clear empties fails here)."""
    from prt_addon import api
    from prt_addon.blender.scene import lighting
    from prt_addon.core.lights.extraction import Light

    bpy = bpy_module
    scene = bpy.context.scene
    objs = _ground_and_box(bpy)
    bpy.ops.object.camera_add(location=(0.0, -6.0, 3.0), rotation=(1.1, 0.0, 0.0))
    scene.camera = bpy.context.object
    sky = np.zeros((9, 3))
    sky[0] = 1.0
    lighting.set_light_override(scene, sky)
    sun = Light(direction=np.array([0.3, 0.2, 0.93]) / np.linalg.norm([0.3, 0.2, 0.93]), power=np.ones(3), angle=0.01)
    lighting.set_lights_override(scene, [sun])
    api.bake(objs, order=3, samples=32)
    api.shade(objs[0], scene)
    api.render_view(scene, 32, 32, display=True)
    assert _filled_containers(), "the set-up filled no cache: the check below would prove nothing"
    bpy.ops.wm.read_homefile(use_empty=True)
    assert _filled_containers() == []
