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
    environment_size: bpy.props.EnumProperty(
        name="Environment Map",
        description=(
            "Size of the world's prefiltered cube map written for other viewers "
            "(EXT_lights_image_based: GGX mips and 9 irradiance coefficients); None leaves it out"
        ),
        items=[
            ("0", "None", "No EXT_lights_image_based"),
            ("64", "64 px", "Faces of 64 x 64 at mip 0 (fastest)"),
            ("128", "128 px", "Faces of 128 x 128 at mip 0"),
        ],
        default=str(gltf.ibl.DEFAULT_SIZE),
    )
    transfer: bpy.props.EnumProperty(
        name="Transfer",
        description='How the transfer coefficients are stored in the file (docs/export.md, "Quantised transfer")',
        items=[
            (
                "snorm16",
                "16-bit",
                "Normalised 16-bit integers with a scale and offset per coefficient (error under 0.01 %)",
            ),
            (
                "snorm8",
                "8-bit",
                "Normalised 8-bit integers: a quarter of float32, errors up to about 0.6 % of the radiance",
            ),
            ("float32", "Float", "32-bit floats: exact, largest, readable by format 1 viewers"),
        ],
        default=gltf.DEFAULT_TRANSFER,
    )

    @classmethod
    def poll(cls, context):
        return context.scene is not None

    def execute(self, context):
        objects = list(context.selected_objects) if self.selected_only else None
        try:
            path = gltf.export_gltf(
                self.filepath, objects, context.scene, int(self.environment_size), transfer=self.transfer
            )
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
