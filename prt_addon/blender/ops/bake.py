"""Operator prt.bake_transfer: bakes the selected meshes, modal with a progress bar, or at once."""

import bpy

from ..bake.job import BakeJob
from ..bake.presets import PRESETS
from ..bake.reports import _report_to_operator, _store_report
from ..bake.runner import TimeSlicedRunner, _running
from ..bake.settings import BakeError, BakeReport, BakeSettings


def bounces_apply(group):
    """Whether the Bounces setting is used: scene shadows on, and a vertex bake (texel bakes
    have no bounces yet)."""
    return group.shadows and not group.self_shadow_only and group.target != "TEXELS"


def settings_from(group):
    """BakeSettings of a PRT_PG_bake_settings. (A module function: a method on the property
    group made bpy 4.2 crash at exit after register/unregister.)"""
    return BakeSettings(
        group.order,
        group.samples,
        group.direction_set,
        group.seed,
        group.shadows,
        group.self_shadow_only,
        group.backend,
        # (greyed out in the panel without scene shadows or for texels: not used then, as Blender does)
        bounces=group.bounces if bounces_apply(group) else 0,
        target=group.target,
        uv_map=group.uv_map or None,
        resolution=group.resolution or None,
        texel_density=group.texel_density,
        adaptive=group.texel_adaptive,
    )


class PRT_OT_bake_transfer(TimeSlicedRunner, bpy.types.Operator):
    """Bake shadowed SH transfer into the selected mesh objects"""

    bl_idname = "prt.bake_transfer"
    bl_label = "Bake"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        if context.mode != "OBJECT":
            cls.poll_message_set("Switch to Object Mode to bake")
            return False
        return True

    def _job(self, context):
        settings = settings_from(context.scene.prt_bake)
        try:
            if _running:
                raise BakeError(
                    "a bake is already running: wait for it to finish, or press Esc to cancel it, then bake again"
                )
            return BakeJob(context.selected_objects, settings, context.evaluated_depsgraph_get())
        except BakeError as exc:
            failed = BakeReport(message=f"Bake not started: {exc}")
            _store_report(context.scene, failed)
            self.report({"ERROR"}, f"PRT: {exc}")
            return None

    def execute(self, context):
        job = self._job(context)
        if job is None:
            return {"CANCELLED"}
        try:
            report = job.run()
        except Exception as exc:
            _store_report(context.scene, BakeReport(message=f"Bake failed: {exc}"))
            self.report({"ERROR"}, f"PRT: bake failed, nothing was changed: {exc}")
            return {"CANCELLED"}
        _store_report(context.scene, report)
        _report_to_operator(self, report)
        return {"FINISHED"}


class PRT_OT_bake_preset(bpy.types.Operator):
    """Set the bake's order, samples and bounces to a preset"""

    bl_idname = "prt.bake_preset"
    bl_label = "Bake Preset"
    bl_options = {"REGISTER", "UNDO"}

    preset: bpy.props.EnumProperty(
        name="Preset",
        description="Order and samples of the bake",
        items=[(key, label, tip) for key, (label, tip, *_values) in PRESETS.items()],
        default="GOOD",
    )

    @classmethod
    def description(cls, _context, properties):
        return PRESETS[properties.preset][1]

    def execute(self, context):
        _label, _tip, order, samples, bounces = PRESETS[self.preset]
        settings = context.scene.prt_bake
        settings.order, settings.samples, settings.bounces = order, samples, bounces
        return {"FINISHED"}


CLASSES = [PRT_OT_bake_transfer, PRT_OT_bake_preset]
