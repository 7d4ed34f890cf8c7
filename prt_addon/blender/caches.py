"""Every cache of the Blender layer, registered in one place, and the clears that empty them.

A module that keeps data between calls registers how to drop it: `on_clear` for everything
(file load, unregister), `on_geometry` for what one mesh's new geometry invalidates. This
module imports nothing of the add-on, so any module may register.
"""

from collections.abc import Callable

_clears: list[Callable[[], None]] = []
_geometry: list[Callable[[object], None]] = []


def on_clear(clear: Callable[[], None]) -> Callable[[], None]:
    """Register `clear` (no arguments) to run on every `clear_all`; returns it (a decorator)."""
    if clear not in _clears:
        _clears.append(clear)
    return clear


def on_geometry(forget: Callable[[object], None]) -> Callable[[object], None]:
    """Register `forget(mesh)` to run when a mesh's geometry changed; returns it (a decorator)."""
    if forget not in _geometry:
        _geometry.append(forget)
    return forget


def clear_all() -> None:
    """Empty every registered cache: on file load and in unregister()."""
    for clear in _clears:
        clear()


def geometry_changed(mesh) -> None:
    """Drop what the new geometry of `mesh` (an original bpy Mesh) invalidates."""
    for forget in _geometry:
        forget(mesh)
