"""Operator prt.set_light_rotation: turn the lighting through the world's Mapping node.

The sidebar's lighting rotation is the Rotation input of the world's Mapping node itself (drawn
with layout.prop on the node socket, no copy), so the sidebar, the node editor, Cycles, EEVEE and
the PRT display always agree. prt.set_light_rotation creates the node when there is none.
"""

import bpy

from ..display.redraw import tag_redraw
from ..world import nodes


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
        if nodes.find_environment_node(context.scene.world) is None:
            cls.poll_message_set("The world has no Environment Texture to rotate: add an HDRI to the World first")
            return False
        return True

    def invoke(self, context, _event):
        self.rotation = nodes.mapping_rotation_euler(context.scene.world)
        return self.execute(context)

    def execute(self, context):
        if not nodes.set_mapping_rotation_euler(context.scene.world, self.rotation):
            self.report({"ERROR"}, "The world has no Environment Texture")
            return {"CANCELLED"}
        tag_redraw()
        return {"FINISHED"}


CLASSES = [PRT_OT_set_light_rotation]
