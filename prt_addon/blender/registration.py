"""The one place where the add-on's classes, properties and handlers are registered.

Each module listed exposes `CLASSES` (registered in order, unregistered in reverse) and may
expose `register_extra()` / `unregister_extra()` for pointer properties, handlers and timers.
Registration is idempotent: register(), unregister(), register() again works in one process,
and a second register() without unregister() first unregisters what is there.
"""

import bpy

from .bake import runner
from .display import handlers
from .ops import bake as bake_ops, display as display_ops, export as export_ops, world as world_ops
from .ui import panels, properties

# Order matters: property groups before the operators and panels that use them; the display's
# handlers after the properties they read; running bakes are stopped before anything goes.
MODULES = [properties, world_ops, bake_ops, display_ops, export_ops, panels, handlers, runner]

_registered = []


def register():
    if _registered:
        unregister()
    for module in MODULES:
        for cls in getattr(module, "CLASSES", ()):
            bpy.utils.register_class(cls)
            _registered.append(cls)
        extra = getattr(module, "register_extra", None)
        if extra is not None:
            extra()


def unregister():
    for module in reversed(MODULES):
        extra = getattr(module, "unregister_extra", None)
        if extra is not None:
            extra()
    while _registered:
        cls = _registered.pop()
        if getattr(cls, "is_registered", True):
            bpy.utils.unregister_class(cls)
