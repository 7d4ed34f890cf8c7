"""What every PRT panel shares: its place in the sidebar, and text that fits the sidebar."""

import textwrap

import bpy


class PRTSubPanel:
    """Placement shared by the feature panels: sub-panels of VIEW3D_PT_prt in the "PRT" tab."""

    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "PRT"
    bl_parent_id = "VIEW3D_PT_prt"


# Average width of a character of Blender's UI font at 100 % scale, in pixels (measured on the
# default font: "Rays traced 1,491,273" is about 130 px), and the panel's inner margins.
CHAR_WIDTH = 6.5
MARGIN = 40


def line_width(context):
    """How many characters fit on one label line of the current region."""
    region = getattr(context, "region", None)
    width = getattr(region, "width", 0) or 300
    scale = (bpy.context.preferences.system.ui_scale if bpy.context.preferences else 0.0) or 1.0
    return max(16, int((width - MARGIN * scale) / (CHAR_WIDTH * scale)))


def wrapped_label(layout, context, text, icon="NONE"):
    """Draw `text` as one or more labels that fit the region (the icon on the first line)."""
    lines = textwrap.wrap(text, line_width(context)) or [""]
    col = layout.column(align=True)
    for index, line in enumerate(lines):
        col.label(text=line, icon=icon if index == 0 else "BLANK1" if icon != "NONE" else "NONE")
    return col


def short_count(n):
    """1234 -> '1.2 k', 1_491_273 -> '1.5 M'."""
    n = float(n)
    for limit, suffix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if abs(n) >= limit:
            return f"{n / limit:.1f} {suffix}"
    return f"{n:.0f}"
