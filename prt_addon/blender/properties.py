"""Settings stored on the scene: `scene.prt` (PRT_PG_scene), saved with the .blend file."""

import bpy


class PRT_PG_scene(bpy.types.PropertyGroup):
    """Root of the add-on's per-scene settings; feature modules add their own groups beside it."""

    show_display: bpy.props.BoolProperty(
        name="Show PRT",
        description="Draw baked objects with PRT lighting in the 3D View",
        default=True,
    )


CLASSES = [PRT_PG_scene]


def register_extra():
    bpy.types.Scene.prt = bpy.props.PointerProperty(type=PRT_PG_scene)


def unregister_extra():
    if hasattr(bpy.types.Scene, "prt"):
        del bpy.types.Scene.prt
