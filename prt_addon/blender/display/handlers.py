"""App handlers of the display (file load, geometry updates) and its timers; all removed on unregister."""

import bpy
from bpy.app.handlers import persistent

from .. import caches
from . import colour, draw, switches


@persistent
def _on_load_pre(*_args):
    draw.remove_draw_handler()
    caches.clear_all()  # (caches are keyed by pointers, which a new file reuses)
    switches.forget()


@persistent
def _on_load_post(*_args):
    draw.add_draw_handler()


@persistent
def _on_depsgraph_update(_scene, depsgraph):
    for update in depsgraph.updates:
        if not update.is_updated_geometry:
            continue
        ident = update.id
        mesh = None
        if isinstance(ident, bpy.types.Mesh):
            mesh = ident.original
        elif isinstance(ident, bpy.types.Object) and ident.type == "MESH":
            mesh = ident.original.data
        if mesh is not None:
            caches.geometry_changed(mesh)


_APP_HANDLERS = (
    ("load_pre", _on_load_pre),
    ("load_post", _on_load_post),
    ("depsgraph_update_post", _on_depsgraph_update),
)


def register_handlers():
    for name, func in _APP_HANDLERS:
        handlers = getattr(bpy.app.handlers, name)
        if func not in handlers:
            handlers.append(func)
    draw.add_draw_handler()
    colour.register_timer()
    switches.register_timer()


def unregister_handlers():
    switches.unregister_timer()
    colour.unregister_timer()
    draw.remove_draw_handler()
    for name, func in _APP_HANDLERS:
        handlers = getattr(bpy.app.handlers, name)
        while func in handlers:
            handlers.remove(func)
    caches.clear_all()


register_extra = register_handlers
unregister_extra = unregister_handlers
