"""An open room of walls and a floor, with coloured materials, for the bounce bakes."""

import warnings

import numpy as np

from helpers.worlds import bundled_hdri_path


def diffuse_material(bpy, name, rgb):
    m = bpy.data.materials.new(name)
    with warnings.catch_warnings():  # (use_nodes is deprecated in Blender 5 and still needed in 4.2)
        warnings.simplefilter("ignore", DeprecationWarning)
        m.use_nodes = True
    nodes = m.node_tree.nodes
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (*rgb, 1.0)
    m.node_tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
    return m


def grid(bpy, name, location, rotation, material, cuts=12):
    bpy.ops.mesh.primitive_grid_add(
        x_subdivisions=cuts, y_subdivisions=cuts, size=4, location=location, rotation=rotation
    )
    obj = bpy.context.active_object
    obj.name = name
    obj.data.materials.append(material)
    return obj


def open_room(bpy, scene, hdri=None, red=(0.8, 0.1, 0.1)):
    """A 4 x 4 floor with a red wall (x = -2), a white wall (x = +2) and a white back wall, open
    at the top and the front, with Suzanne inside; a uniform white world or an HDRI."""
    world = bpy.data.worlds.new("room world")
    scene.world = world
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    if hdri is None:
        background.inputs[0].default_value = (1.0, 1.0, 1.0, 1.0)
    else:
        env = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
        env.image = bpy.data.images.load(bundled_hdri_path(hdri))
        world.node_tree.links.new(env.outputs[0], background.inputs[0])
    white = diffuse_material(bpy, "white", (0.8, 0.8, 0.8))
    objs = [
        grid(bpy, "floor", (0, 0, 0), (0, 0, 0), white),
        grid(bpy, "wall_red", (-2, 0, 2), (0, np.pi / 2, 0), diffuse_material(bpy, "red", red)),
        grid(bpy, "wall_white", (2, 0, 2), (0, -np.pi / 2, 0), white),
        grid(bpy, "wall_back", (0, 2, 2), (np.pi / 2, 0, 0), white),
    ]
    bpy.ops.mesh.primitive_monkey_add(location=(0, 0, 0.7), size=1.0)
    suzanne = bpy.context.active_object
    suzanne.name = "Suzanne"
    suzanne.modifiers.new("subdivision", "SUBSURF").levels = 1
    bpy.ops.object.shade_smooth()
    bpy.ops.object.modifier_apply(modifier="subdivision")
    suzanne.data.materials.append(white)
    return objs + [suzanne]
