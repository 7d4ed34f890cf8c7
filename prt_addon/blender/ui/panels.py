"""The sidebar tab "PRT": the root panel (display, lighting rotation), World, Bake and Display panels."""

import bpy

from ..display.albedo_texture import notes as albedo_notes
from ..display.draw import draws_in
from ..display.material_maps import notes as map_notes
from ..scene import lighting, storage
from ..world import light_split, nodes
from .bake_panel import VIEW3D_PT_prt_bake, VIEW3D_PT_prt_bake_options, VIEW3D_PT_prt_bake_report
from .sidebar import PRTSubPanel, wrapped_label

SHADING_NAMES = {"WIREFRAME": "Wireframe", "MATERIAL": "Material Preview", "RENDERED": "Rendered"}


def shading_note(scene, space):
    """The root panel's line when the 3D View's shading hides the overlay, else None."""
    if not scene.prt.show_display or draws_in(space):
        return None
    kind = space.shading.type
    return f"Not drawn in {SHADING_NAMES.get(kind, kind.title())} shading: PRT draws in Solid"


class VIEW3D_PT_prt(bpy.types.Panel):
    bl_idname = "VIEW3D_PT_prt"
    bl_label = "PRT Lighting"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "PRT"

    def draw(self, context):
        layout, scene = self.layout, context.scene
        layout.prop(scene.prt, "show_display")
        note = shading_note(scene, context.space_data)
        if note:
            wrapped_label(layout, context, note, icon="INFO")
        # The lighting's turn first: the control a user reaches for after every bake.
        col = layout.column()
        mapping = nodes.find_mapping_node(scene.world)
        if nodes.find_environment_node(scene.world) is None:
            col.label(text="World has no Environment Texture", icon="INFO")
        elif scene.prt_world.stored_order < 1:  # (World Lighting, closed by default, holds its settings)
            col.operator("prt.project_world", icon="WORLD")
        elif mapping is None:
            col.operator("prt.set_light_rotation", text="Add Lighting Rotation", icon="WORLD")
        else:
            col.prop(mapping.inputs["Rotation"], "default_value", text="Lighting Rotation")


class VIEW3D_PT_prt_world(PRTSubPanel, bpy.types.Panel):
    bl_idname = "VIEW3D_PT_prt_world"
    bl_label = "World Lighting"
    # Closed: used once per world (Project World is also in the root panel until then), and open
    # it pushed the Display panel and the bake's result below the sidebar's fold.
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        settings = context.scene.prt_world
        layout = self.layout
        layout.prop(settings, "order")
        layout.prop(settings, "split_lights")
        if settings.split_lights:
            row = layout.row(align=True)
            if settings.auto_threshold:
                row.prop(settings, "auto_threshold", text="Threshold: Auto", toggle=True)
            else:
                row.prop(settings, "auto_threshold", text="Auto", toggle=True)
                row.prop(settings, "light_threshold")
            row.prop(settings, "max_lights")
        layout.operator("prt.project_world")
        if settings.stored_order < 1:
            layout.label(text="No world lighting stored")
            return
        lines = layout.column(align=True)
        for line in light_split.summary(settings):
            lines.label(text=line)


class VIEW3D_PT_prt_world_details(PRTSubPanel, bpy.types.Panel):
    bl_idname = "VIEW3D_PT_prt_world_details"
    bl_label = "Details"
    bl_parent_id = "VIEW3D_PT_prt_world"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        return context.scene.prt_world.stored_order >= 1

    def draw(self, context):
        settings = context.scene.prt_world
        layout = self.layout
        col = layout.column(align=True)
        col.label(text=f"Order {settings.stored_order} from {settings.source_kind.lower()}")
        if settings.image_name:
            w, h = settings.image_size
            col.label(text=f"{settings.image_name} ({w}x{h})")
        if settings.mapping_node:
            wrapped_label(col, context, f"Turned by the Mapping node '{settings.mapping_node}'")
        col.label(text=f"Projected in {settings.seconds:.2f} s")
        if settings.message:
            for note in settings.message.split("; "):
                wrapped_label(layout, context, note, icon="INFO")


class VIEW3D_PT_prt_display(PRTSubPanel, bpy.types.Panel):
    bl_idname = "VIEW3D_PT_prt_display"
    bl_label = "Display"

    def draw(self, context):
        layout = self.layout
        scene = context.scene
        settings = scene.prt_display
        layout.prop(settings, "albedo_source")
        layout.prop(settings, "specular")
        if settings.albedo_source == "ATTRIBUTE":
            layout.prop(settings, "albedo_attribute")
        row = layout.row()
        row.active = bool(lighting.world_lights(scene))  # greyed out while there is no split light
        row.prop(settings, "show_light_directions")
        if lighting.world_light(scene) is None:
            wrapped_label(layout, context, "No world lighting yet: press Project World", icon="ERROR")
        obj = context.active_object
        if obj is not None and obj.type == "MESH" and storage.RECORD in obj.data:
            info, problem = storage.usable_bake(obj.data, check_topology=False)
            if info is None:
                wrapped_label(layout, context, f"{obj.name} is not drawn: {problem}", icon="ERROR")
            else:
                layout.label(text=f"{obj.name}: drawn at order {info.order}")
                if settings.albedo_source == "MATERIAL":
                    said = albedo_notes(obj) + (map_notes(obj) if settings.specular else [])
                    for note in said:
                        wrapped_label(layout, context, note, icon="INFO")


CLASSES = [
    VIEW3D_PT_prt,
    VIEW3D_PT_prt_world,
    VIEW3D_PT_prt_world_details,
    VIEW3D_PT_prt_bake,
    VIEW3D_PT_prt_bake_options,
    VIEW3D_PT_prt_bake_report,
    VIEW3D_PT_prt_display,
]
