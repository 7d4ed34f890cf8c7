"""The Bake panel of the PRT tab: presets, settings, the button, a one-line result, the report."""

import bpy

from ...core.trace import raytrace
from ..bake.estimate import estimate
from ..bake.job import status
from ..bake.presets import PRESETS, preset_of
from ..bake.reports import last_report
from ..bake.settings import FALLBACK_SLOWDOWN, BakeError, BakeReport, texel_memory
from ..ops.bake import bounces_apply, settings_from
from .sidebar import PRTSubPanel, short_count, wrapped_label


def _report(scene):
    data = last_report(scene)
    if not data:
        return None
    try:
        return BakeReport(**{k: v for k, v in data.items() if k in BakeReport.__dataclass_fields__})
    except (ValueError, TypeError):
        return None


def result_line(report):
    """'0.56 s - 1.5 M rays - about 3 % noise': what an artist reads of a finished bake."""
    noise = 100.0 * report.error_estimate_relative
    noise_text = f"about {noise:.0f} % noise" if noise >= 1.0 else f"under 1 % noise ({noise:.2f})"
    bounces = f" - {report.bounces} bounces" if report.bounces else ""
    return f"{report.seconds:.2f} s - {short_count(report.rays_traced)} rays{bounces} - {noise_text}"


def texel_settings(layout, context, settings):
    """The lightmap's UV map and size, and the memory a texel bake of the selection takes."""
    col = layout.column(align=True)
    obj = context.active_object
    if obj is not None and obj.type == "MESH":
        col.prop_search(settings, "uv_map", obj.data, "uv_layers", text="UV Map")
    else:
        col.prop(settings, "uv_map")
    col.prop(settings, "resolution")
    if not settings.resolution:
        col.prop(settings, "texel_density")
    col.prop(settings, "texel_adaptive")
    meshes = sum(1 for o in context.selected_objects if o.type == "MESH")
    if settings.resolution and meshes:
        need = meshes * texel_memory(settings.resolution, settings.order)
        wrapped_label(layout, context, f"Memory: about {need / 2**20:,.0f} MB for {meshes} mesh(es)", icon="INFO")


def estimate_line(layout, context, settings):
    """'Estimate: about 3 s, up to 250 MB (11 GB available)' for the selection, or why it will not fit."""
    try:
        found = estimate(context.selected_objects[:256], settings_from(settings), context.scene)
    except (BakeError, ReferenceError):
        return
    if not found.elements:
        return
    if found.fits:
        wrapped_label(layout, context, f"Estimate: {found.line()}", icon="TIME")
    else:
        wrapped_label(layout, context, f"Too large: {found.line()}", icon="ERROR")


class VIEW3D_PT_prt_bake(PRTSubPanel, bpy.types.Panel):
    bl_idname = "VIEW3D_PT_prt_bake"
    bl_label = "Bake Transfer"

    def draw(self, context):
        layout = self.layout
        settings = context.scene.prt_bake
        current = preset_of(settings.order, settings.samples, settings.bounces)
        row = layout.row(align=True)
        for key, (label, *_values) in PRESETS.items():
            op = row.operator("prt.bake_preset", text=label, depress=current == key)
            op.preset = key
        if current == "CUSTOM":
            layout.label(text="Custom settings")
        col = layout.column(align=True)
        col.prop(settings, "order")
        col.prop(settings, "samples")
        layout.prop(settings, "shadows")
        sub = layout.column(align=True)
        sub.enabled = settings.shadows
        sub.prop(settings, "self_shadow_only")
        bounce_row = layout.column(align=True)
        bounce_row.enabled = bounces_apply(settings)
        bounce_row.prop(settings, "bounces")
        if settings.target != "VERTICES" and settings.bounces and settings.adaptive:
            bounce_row.label(text="Texels: every texel traced (no adaptive) with bounces")
        layout.prop(settings, "target")
        if settings.target != "VERTICES":
            texel_settings(layout, context, settings)
        if not raytrace.EMBREE_AVAILABLE:
            if settings.backend == "EMBREE":
                wrapped_label(layout, context, "Embree is not available here: choose Auto or BVH Tree", icon="ERROR")
            else:
                wrapped_label(
                    layout,
                    context,
                    f"Fast ray tracing (Embree) is not available here: baking "
                    f"is about {FALLBACK_SLOWDOWN} times slower",
                    icon="INFO",
                )
        estimate_line(layout, context, settings)
        layout.operator("prt.bake_transfer", text="Bake", icon="RENDER_STILL")
        obj = context.active_object
        if obj is not None and obj.type == "MESH":
            state, reason = status(obj, use_cache=True)
            if state == "fresh":
                layout.label(text=f"{obj.name}: baked", icon="CHECKMARK")
            elif state == "stale":
                wrapped_label(layout, context, f"{obj.name}: bake again ({reason.split(':')[0]})", icon="ERROR")
            else:
                layout.label(text=f"{obj.name}: not baked", icon="DOT")
        stale = [
            o.name
            for o in context.selected_objects[:16]
            if o.type == "MESH" and o != obj and status(o, use_cache=True)[0] == "stale"
        ]
        if stale:
            wrapped_label(layout, context, "Bake again: " + ", ".join(stale), icon="ERROR")
        report = _report(context.scene)
        if report is not None:
            if report.ok:
                wrapped_label(layout, context, result_line(report), icon="INFO")
                if report.enclosed_note():
                    wrapped_label(layout, context, report.enclosed_note(), icon="LIGHT")
            else:
                wrapped_label(layout, context, report.headline(), icon="ERROR")


class VIEW3D_PT_prt_bake_options(PRTSubPanel, bpy.types.Panel):
    bl_idname = "VIEW3D_PT_prt_bake_options"
    bl_label = "Options"
    bl_parent_id = "VIEW3D_PT_prt_bake"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        settings = context.scene.prt_bake
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.prop(settings, "direction_set")
        layout.prop(settings, "seed")
        layout.prop(settings, "backend")


class VIEW3D_PT_prt_bake_report(PRTSubPanel, bpy.types.Panel):
    bl_idname = "VIEW3D_PT_prt_bake_report"
    bl_label = "Report"
    bl_parent_id = "VIEW3D_PT_prt_bake"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        return _report(context.scene) is not None

    def draw(self, context):
        report = _report(context.scene)
        if report is None:
            return
        for line in report.report_lines():
            wrapped_label(self.layout, context, line)


CLASSES = [VIEW3D_PT_prt_bake, VIEW3D_PT_prt_bake_options, VIEW3D_PT_prt_bake_report]
