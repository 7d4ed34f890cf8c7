"""Stand-ins for driving a modal operator headless: a fake Event and an operator instance."""


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
        self._store = lambda ctx, report: cls._store(self, ctx, report)
        from prt_addon.blender.bake.reports import _scene_key

        self._scene_key = _scene_key(__import__("bpy").context.scene)  # (as invoke() keeps it)
        self.modal = lambda ctx, event: cls.modal(self, ctx, event)
