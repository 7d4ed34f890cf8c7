"""A closed room lit through a skylight, with a table and a box: the defaults' test scene."""

import numpy as np

from helpers.rooms import open_room


def skylight_room(bpy, scene, hdri="interior", quad_back_wall=False):
    """open_room's floor and three walls (without Suzanne), a front wall and a ceiling with a
    1 x 1 skylight, a table top on legs and a box: most rays from inside hit a surface. With
    quad_back_wall the back wall is one quad (four vertices, all in the room's corners)."""
    objs = [o for o in open_room(bpy, scene, hdri=hdri) if o.name != "Suzanne"]
    bpy.data.objects.remove(bpy.data.objects["Suzanne"])
    white = bpy.data.materials["white"]
    if quad_back_wall:
        back = bpy.data.objects["wall_back"]
        objs.remove(back)
        bpy.data.objects.remove(back)
        bpy.ops.mesh.primitive_plane_add(size=4, location=(0, 2, 2), rotation=(np.pi / 2, 0, 0))
        back = bpy.context.active_object
        back.name = "wall_back"
        back.data.materials.append(white)
        objs.append(back)
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
    bpy.ops.mesh.primitive_cube_add(size=1, location=(-0.7, 0.6, 0.75), scale=(0.8, 0.6, 0.04))
    table = bpy.context.active_object
    table.name = "table"
    legs = []
    for x, y in ((-1, -1), (-1, 1), (1, -1), (1, 1)):
        bpy.ops.mesh.primitive_cube_add(size=1, location=(-0.7 + 0.35 * x, 0.6 + 0.25 * y, 0.365))
        bpy.context.active_object.scale = (0.05, 0.05, 0.73)
        legs.append(bpy.context.active_object)
    bpy.ops.object.select_all(action="DESELECT")
    for obj in (table, *legs):
        obj.select_set(True)
    bpy.context.view_layer.objects.active = table
    bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
    bpy.ops.object.join()
    for obj in (front, ceiling, box, table):
        obj.data.materials.append(white)
    bpy.ops.object.select_all(action="DESELECT")
    return objs + [front, ceiling, box, table]
