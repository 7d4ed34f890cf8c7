"""Sidebar tab "PRT" in the 3D View. Feature panels use bl_parent_id = "VIEW3D_PT_prt"."""

import bpy


class VIEW3D_PT_prt(bpy.types.Panel):
    bl_idname = "VIEW3D_PT_prt"
    bl_label = "PRT Lighting"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "PRT"

    def draw(self, context):
        settings = context.scene.prt
        self.layout.prop(settings, "show_display")


class PRTSubPanel:
    """Placement shared by the feature panels: sub-panels of VIEW3D_PT_prt in the "PRT" tab."""

    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "PRT"
    bl_parent_id = "VIEW3D_PT_prt"


CLASSES = [VIEW3D_PT_prt]
