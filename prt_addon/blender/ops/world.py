"""Operator prt.project_world: project the scene's World into SH and store it on the scene."""

import bpy

from ..world import projection as world


class PRT_OT_project_world(bpy.types.Operator):
    """Project the scene's World lighting into spherical harmonics and store it on the scene"""

    bl_idname = "prt.project_world"
    bl_label = "Project World"
    bl_options = {"REGISTER", "UNDO"}

    order: bpy.props.IntProperty(
        name="Order",
        description="0: use the scene's World Lighting order",
        default=0,
        min=0,
        max=world.MAX_ORDER,
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
        for note in result.info:
            self.report({"INFO"}, note)
        self.report(
            {"INFO"},
            f"World projected at order {result.order} from {result.source.kind.lower()} in "
            f"{result.seconds:.2f} s; beyond the order: {100.0 * result.truncation:.1f} % of the radiance energy, "
            f"{100.0 * result.diffuse_truncation:.2g} % of the diffuse shading energy",
        )
        if result.split:
            self.report(
                {"INFO"},
                f"{len(result.lights)} light(s) split off, {100.0 * result.light_share:.0f} % of the world's light"
                if result.lights
                else "No compact bright source: no lights split off",
            )
        return {"FINISHED"}


CLASSES = [PRT_OT_project_world]
