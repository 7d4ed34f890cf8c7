"""Operator prt.export_gltf: the baked objects and the world lighting to a binary glTF (.glb)."""

import bpy
from bpy_extras.io_utils import ExportHelper

from ..export import gltf


class PRT_OT_export_gltf(bpy.types.Operator, ExportHelper):
    """Export the baked objects with their PRT transfer and the world lighting to a binary glTF file"""

    bl_idname = "prt.export_gltf"
    bl_label = "Export PRT Lighting (.glb)"
    bl_options = {"REGISTER"}

    filename_ext = ".glb"
    filter_glob: bpy.props.StringProperty(default="*.glb", options={"HIDDEN"})

    selected_only: bpy.props.BoolProperty(
        name="Selected Only",
        description="Export only the selected objects (else every baked mesh of the scene)",
        default=False,
    )

    @classmethod
    def poll(cls, context):
        return context.scene is not None

    def execute(self, context):
        objects = list(context.selected_objects) if self.selected_only else None
        try:
            path = gltf.export_gltf(self.filepath, objects, context.scene)
        except ValueError as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        self.report({"INFO"}, f"PRT Lighting exported to {path}")
        return {"FINISHED"}


def menu_func(self, _context):
    self.layout.operator(PRT_OT_export_gltf.bl_idname, text="PRT Lighting (.glb)")


def register_extra():
    bpy.types.TOPBAR_MT_file_export.remove(menu_func)
    bpy.types.TOPBAR_MT_file_export.append(menu_func)


def unregister_extra():
    bpy.types.TOPBAR_MT_file_export.remove(menu_func)


CLASSES = [PRT_OT_export_gltf]
