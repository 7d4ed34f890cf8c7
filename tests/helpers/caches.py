"""Cache tests' scene: a ground and a box, baked."""


def _ground_and_box(bpy):
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 0.5))
    return list(bpy.context.scene.objects)
