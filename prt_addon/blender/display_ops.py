"""Display settings, the lighting-rotation control and the display sub-panel of the "PRT" tab.

The sidebar's lighting rotation is the Rotation input of the world's Mapping node itself (drawn
with layout.prop on the node socket, no copy), so the sidebar, the node editor, Cycles, EEVEE and
the PRT display always agree. prt.set_light_rotation creates the node when there is none.
"""


import bpy

from . import display
from .panels import PRTSubPanel


class PRT_PG_display(bpy.types.PropertyGroup):
    # No Python get/set/update callbacks here: with them, bpy 4.2 (as a module) crashes at exit
    # after unregister. The draw reads these every redraw; the batch cache key includes them.
    albedo_source: bpy.props.EnumProperty(
        name="Albedo",
        items=[
            ("MATERIAL", "Material", "Base colour of each material slot"),
            ("ATTRIBUTE", "Color Attribute", "A colour attribute of the mesh"),
            ("WHITE", "White", "No albedo: radiance only"),
        ],
        default="MATERIAL",
    )
    albedo_attribute: bpy.props.StringProperty(
        name="Attribute",
        description="Colour attribute used as albedo (empty: the mesh's active colour attribute)",
        default="",
    )


class PRT_OT_set_light_rotation(bpy.types.Operator):
    """Rotate the world lighting: set the rotation of the Mapping node in front of the world's
    Environment Texture, creating the node if needed (Cycles, EEVEE and the PRT display follow)"""

    bl_idname = "prt.set_light_rotation"
    bl_label = "Set Lighting Rotation"
    bl_options = {"REGISTER", "UNDO"}

    rotation: bpy.props.FloatVectorProperty(name="Rotation", size=3, subtype="EULER", unit="ROTATION")

    @classmethod
    def poll(cls, context):
        if context.scene is None or context.scene.world is None:
            cls.poll_message_set("The scene has no World: add one in the World properties")
            return False
        if display.find_environment_node(context.scene.world) is None:
            cls.poll_message_set("The world has no Environment Texture to rotate: "
                                 "add an HDRI to the World first")
            return False
        return True

    def invoke(self, context, _event):
        self.rotation = display.mapping_rotation_euler(context.scene.world)
        return self.execute(context)

    def execute(self, context):
        if not display.set_mapping_rotation_euler(context.scene.world, self.rotation):
            self.report({"ERROR"}, "The world has no Environment Texture")
            return {"CANCELLED"}
        return {"FINISHED"}


class VIEW3D_PT_prt_display(PRTSubPanel, bpy.types.Panel):
    bl_idname = "VIEW3D_PT_prt_display"
    bl_label = "Display"

    def draw(self, context):
        layout = self.layout
        scene = context.scene
        settings = scene.prt_display
        col = layout.column()
        mapping = display.find_mapping_node(scene.world)
        if display.find_environment_node(scene.world) is None:
            col.label(text="World has no Environment Texture", icon="INFO")
        elif mapping is None:
            col.operator(PRT_OT_set_light_rotation.bl_idname, text="Add Lighting Rotation", icon="WORLD")
        else:
            col.prop(mapping.inputs["Rotation"], "default_value", text="Lighting Rotation")
        layout.prop(settings, "albedo_source")
        if settings.albedo_source == "ATTRIBUTE":
            layout.prop(settings, "albedo_attribute")
        if display.world_light(scene) is None:
            layout.label(text="No projected world lighting", icon="ERROR")
        obj = context.active_object
        if obj is not None and obj.type == "MESH" and display.RECORD_KEY in obj.data:
            info, problem = display.bake_status(obj.data, check_topology=False)
            if info is None:
                layout.label(text=f"{obj.name}: not displayed ({problem})", icon="ERROR")
            else:
                path = "vertex attributes" if display.shader_mode(info.count) == "ATTR" else "texture"
                layout.label(text=f"{obj.name}: order {info.order}, transfer from {path}")
        view = scene.view_settings
        if view.view_transform != "Standard":
            layout.label(text=f"Viewport shows radiance as 'Standard', not '{view.view_transform}'", icon="INFO")


CLASSES = [PRT_PG_display, PRT_OT_set_light_rotation, VIEW3D_PT_prt_display]


def register_extra():
    bpy.types.Scene.prt_display = bpy.props.PointerProperty(type=PRT_PG_display)
    display.register_handlers()


def unregister_extra():
    display.unregister_handlers()
    if hasattr(bpy.types.Scene, "prt_display"):
        del bpy.types.Scene.prt_display
