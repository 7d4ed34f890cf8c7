"""A closed room lit through a skylight, with a table and a box: the defaults' test scene."""

import numpy as np

from helpers.rooms import open_room


def skylight_room(bpy, scene, hdri="interior"):
    """open_room's floor and three walls (without Suzanne), a front wall and a ceiling with a
    1 x 1 skylight, a table top on legs and a box: most rays from inside hit a surface."""
    objs = [o for o in open_room(bpy, scene, hdri=hdri) if o.name != "Suzanne"]
    bpy.data.objects.remove(bpy.data.objects["Suzanne"])
    white = bpy.data.materials["white"]
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=12, y_subdivisions=12, size=4, location=(0, -2, 2))
    front = bpy.context.active_object
    front.rotation_euler = (-np.pi / 2, 0, 0)
    front.name = "wall_front"
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=16, y_subdivisions=16, size=4, location=(0, 0, 4))
    ceiling = bpy.context.active_object
    ceiling.rotation_euler = (np.pi, 0, 0)  # facing down, into the room
    ceiling.name = "ceiling"
    mesh = ceiling.data
    hole = [p.index for p in mesh.polygons if abs(p.center.x) < 0.5 and abs(p.center.y - 0.5) < 0.5]
    import bmesh

    bm = bmesh.new()
    bm.from_mesh(mesh)
    bm.faces.ensure_lookup_table()
    bmesh.ops.delete(bm, geom=[bm.faces[i] for i in hole], context="FACES")
    bm.to_mesh(mesh)
    bm.free()
    bpy.ops.mesh.primitive_cube_add(size=1, location=(0.8, -0.6, 0.5))
    box = bpy.context.active_object
    box.name = "box"
    box.modifiers.new("subdivide", "SUBSURF").subdivision_type = "SIMPLE"
    box.modifiers["subdivide"].levels = 3
    bpy.ops.object.modifier_apply(modifier="subdivide")
    for obj in (front, ceiling, box):
        obj.data.materials.append(white)
    bpy.ops.object.select_all(action="DESELECT")
    return objs + [front, ceiling, box]
