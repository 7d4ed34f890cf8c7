"""A timer that redraws the 3D Views when a display switch changes, also when a script sets it.

The switches are polled rather than given RNA update callbacks: bpy 4.2 as a module crashes at
exit after an extension whose properties have an update callback is uninstalled.
"""

import bpy

from .redraw import tag_redraw

POLL_INTERVAL = 0.1  # seconds between the timer's looks at the switches

_seen = {}  # scene pointer -> the switches' values the last look saw


def switch_values(scene):
    """The values of the switches that change what the 3D View draws, or None without settings."""
    prt, display = getattr(scene, "prt", None), getattr(scene, "prt_display", None)
    if prt is None or display is None:
        return None
    return (prt.show_display, display.show_light_directions)


def _window_scenes():
    wm = getattr(bpy.context, "window_manager", None)
    scenes = [window.scene for window in wm.windows] if wm is not None else []
    return [scene for scene in scenes if scene is not None]


def look(scenes):
    """Compare each scene's switches with the last look; redraw once if any changed. True if so."""
    changed = False
    for scene in scenes:
        key, values = scene.as_pointer(), switch_values(scene)
        if key in _seen and _seen[key] != values:
            changed = True
        _seen[key] = values
    if changed:
        tag_redraw()
    return changed


def _poll():
    look(_window_scenes())
    return POLL_INTERVAL


def forget():
    """Drop what the looks saw (a file is loading: its scenes may reuse the old pointers)."""
    _seen.clear()


def register_timer():
    forget()
    if not bpy.app.timers.is_registered(_poll):
        bpy.app.timers.register(_poll, first_interval=0.0, persistent=True)


def unregister_timer():
    if bpy.app.timers.is_registered(_poll):
        bpy.app.timers.unregister(_poll)
    forget()
