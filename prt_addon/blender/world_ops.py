"""Operator prt.project_world, the stored world lighting (scene.prt_world) and its panel.

The coefficients themselves are ID-property arrays on the scene (see world.py and docs/world.md);
PRT_PG_world holds the order to project at and the record of the last projection.
"""

import bpy

from . import world
from .panels import PRTSubPanel


class PRT_PG_world(bpy.types.PropertyGroup):
    order: bpy.props.IntProperty(
        name="Order",
        description="SH order of the world lighting (order**2 coefficients per colour channel)",
        default=8,
        min=1,
        max=world.MAX_ORDER,
        soft_max=16,
    )
    stored_order: bpy.props.IntProperty(name="Stored Order", description="0: nothing stored", default=0)
    source_kind: bpy.props.StringProperty(name="Source", description="IMAGE, COLOR or RENDER")
    world_name: bpy.props.StringProperty(name="World")
    source_node: bpy.props.StringProperty(name="Node")
    image_name: bpy.props.StringProperty(name="Image")
    image_size: bpy.props.IntVectorProperty(name="Image Size", size=2)
    projected_size: bpy.props.IntVectorProperty(name="Projected Size", size=2)
    mapping_node: bpy.props.StringProperty(name="Mapping Node")
    mapping_type: bpy.props.StringProperty(name="Mapping Type")
    mapping_rotation: bpy.props.FloatVectorProperty(name="Mapping Rotation", size=3, subtype="EULER")
    rotation_matrix: bpy.props.FloatVectorProperty(
        name="SH Rotation",
        description="Q, row-major: world coefficients = rotate(stored coefficients, Q)",
        size=9,
        default=(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
    )
    seconds: bpy.props.FloatProperty(name="Time", unit="TIME_ABSOLUTE")
    truncation: bpy.props.FloatProperty(
        name="Truncation",
        description="Fraction of the L2 luminance energy of the world beyond the stored order",
        subtype="FACTOR",
    )
    diffuse_truncation: bpy.props.FloatProperty(
        name="Diffuse Truncation",
        description="Fraction of the L2 luminance energy of unshadowed diffuse shading beyond the stored order",
        subtype="FACTOR",
    )
    message: bpy.props.StringProperty(name="Notes")
    token: bpy.props.StringProperty(name="Token", description="Changes at every projection")


class PRT_OT_project_world(bpy.types.Operator):
    """Project the scene's World lighting into spherical harmonics and store it on the scene"""

    bl_idname = "prt.project_world"
    bl_label = "Project World"
    bl_options = {"REGISTER", "UNDO"}

    order: bpy.props.IntProperty(
        name="Order", description="0: use the scene's World Lighting order",
        default=0, min=0, max=world.MAX_ORDER,
    )

    @classmethod
    def poll(cls, context):
        return context.scene is not None

    def execute(self, context):
        scene = context.scene
        try:
            result = world.project_and_store(scene, self.order or None)
        except world.WorldError as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        for note in result.warnings:
            self.report({"WARNING"}, note)
        self.report(
            {"INFO"},
            f"World projected at order {result.order} from {result.source.kind.lower()} in "
            f"{result.seconds:.2f} s; beyond the order: {100.0 * result.truncation:.1f} % of the radiance energy, "
            f"{100.0 * result.diffuse_truncation:.2g} % of the diffuse shading energy",
        )
        return {"FINISHED"}


class VIEW3D_PT_prt_world(PRTSubPanel, bpy.types.Panel):
    bl_idname = "VIEW3D_PT_prt_world"
    bl_label = "World Lighting"

    def draw(self, context):
        settings = context.scene.prt_world
        layout = self.layout
        layout.prop(settings, "order")
        layout.operator(PRT_OT_project_world.bl_idname)
        if settings.stored_order < 1:
            layout.label(text="No world lighting stored")
            return
        col = layout.column(align=True)
        col.label(text=f"Order {settings.stored_order} from {settings.source_kind.lower()}")
        if settings.image_name:
            w, h = settings.image_size
            col.label(text=f"{settings.image_name} ({w}x{h})")
        if settings.mapping_node:
            col.label(text=f"Rotated by {settings.mapping_node} ({settings.mapping_type.lower()})")
        col.label(text=f"{settings.seconds:.2f} s, beyond the order: radiance {100.0 * settings.truncation:.1f} %, "
                  f"diffuse {100.0 * settings.diffuse_truncation:.2g} %")
        if settings.message:
            col.label(text=settings.message, icon="ERROR")


CLASSES = [PRT_PG_world, PRT_OT_project_world, VIEW3D_PT_prt_world]


def register_extra():
    bpy.types.Scene.prt_world = bpy.props.PointerProperty(type=PRT_PG_world)


def unregister_extra():
    if hasattr(bpy.types.Scene, "prt_world"):
        del bpy.types.Scene.prt_world
