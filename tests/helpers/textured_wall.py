"""A floor beside a single-quad wall whose image is red on one half and blue on the other, or the
same wall as a red and a blue quad of constant colour, under a uniform white world."""

import warnings

import numpy as np

from helpers.rooms import diffuse_material, grid

RED, BLUE = (0.8, 0.1, 0.1), (0.1, 0.1, 0.8)


def wall(bpy, name, y_range, material):
    """A single quad at x = -2 facing +x, 4 high, spanning y_range, u along y."""
    y0, y1 = y_range
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([(-2, y0, 0), (-2, y1, 0), (-2, y1, 4), (-2, y0, 4)], [], [(0, 1, 2, 3)])
    mesh.uv_layers.new(name="UVMap")
    co = np.array([mesh.vertices[i].co[:] for i in (lp.vertex_index for lp in mesh.loops)])
    # u from 0.07 to 0.93 (0.5 at y = 0): over half a texel inside the 8-texel image's edges, where
    # Linear and Repeat would blend in the other side's colour.
    uv = np.stack([0.07 + 0.86 * (co[:, 1] + 2.0) / 4.0, 0.07 + 0.86 * co[:, 2] / 4.0], axis=1).astype(np.float32)
    mesh.uv_layers[0].data.foreach_set("uv", uv.ravel())
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def room(bpy, scene, textured):
    world = bpy.data.worlds.new("white")
    scene.world = world
    with warnings.catch_warnings():  # (deprecated in Blender 5, still needed in 4.2)
        warnings.simplefilter("ignore", DeprecationWarning)
        world.use_nodes = True
    world.node_tree.nodes["Background"].inputs[0].default_value = (1.0, 1.0, 1.0, 1.0)
    floor = grid(bpy, "floor", (0, 0, 0), (0, 0, 0), diffuse_material(bpy, "white", (0.8, 0.8, 0.8)))
    if textured:
        image = bpy.data.images.new("halves", 8, 8, float_buffer=True)
        pixels = np.ones((8, 8, 4), np.float32)
        pixels[:, :4, :3], pixels[:, 4:, :3] = RED, BLUE  # (u < 0.5: red)
        image.pixels.foreach_set(pixels.ravel())
        material = diffuse_material(bpy, "halves", (1.0, 1.0, 1.0))
        node = material.node_tree.nodes.new("ShaderNodeTexImage")
        node.image = image
        bsdf = material.node_tree.nodes["Diffuse BSDF"]
        material.node_tree.links.new(node.outputs["Color"], bsdf.inputs["Color"])
        wall(bpy, "wall", (-2.0, 2.0), material)
    else:
        wall(bpy, "wall_red", (-2.0, 0.0), diffuse_material(bpy, "red", RED))
        wall(bpy, "wall_blue", (0.0, 2.0), diffuse_material(bpy, "blue", BLUE))
    return floor
