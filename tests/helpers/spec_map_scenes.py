"""Principled materials whose Roughness and Metallic (a packed metallic-roughness map), Specular IOR Level or IOR come from an image, and the sphere they are drawn on."""

import numpy as np

from helpers.display_scenes import clamped_cosine_rows, local_positions, write_bake

# The map's quadrants (u half, v half) -> (roughness in G, metallic in B): exact in 8 bits.
QUADRANTS = {(0, 0): (0.2, 0.0), (1, 0): (0.8, 0.0), (0, 1): (0.2, 1.0), (1, 1): (0.8, 1.0)}
ID_COLOURS = {(0, 0): (1.0, 0.0, 0.0), (1, 0): (0.0, 1.0, 0.0), (0, 1): (0.0, 0.0, 1.0), (1, 1): (0.0, 0.0, 0.0)}
SIZE = 64


def quadrant_image(bpy, name, values, colour_space="Non-Color"):
    """A SIZE x SIZE byte image: per quadrant (u half, v half) of `values` its RGB."""
    image = bpy.data.images.new(name, SIZE, SIZE)
    image.colorspace_settings.name = colour_space  # (before the pixels: it regenerates the image)
    px = np.ones((SIZE, SIZE, 4), np.float32)
    half = SIZE // 2
    for (u, v), rgb in values.items():
        px[v * half : (v + 1) * half, u * half : (u + 1) * half, :3] = rgb
    image.pixels.foreach_set(px.ravel())
    return image


def orm_image(bpy, name="orm", colour_space="Non-Color"):
    """The metallic-roughness map: R 1 (occlusion), G roughness, B metallic, per QUADRANTS."""
    return quadrant_image(bpy, name, {q: (1.0, r, m) for q, (r, m) in QUADRANTS.items()}, colour_space)


def principled(bpy, name, base=(0.8, 0.8, 0.8), roughness=0.5, metallic=0.0):
    mat = bpy.data.materials.new(name)
    if mat.node_tree is None:
        mat.use_nodes = True
    bsdf = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (*base, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = metallic
    return mat, bsdf


def orm_material(bpy, image, name="mapped", base=(0.8, 0.8, 0.8)):
    """Roughness from the image's G and Metallic from its B through a Separate Color node (the
    constants left at 0.5 and 0.5, which the draw must not use)."""
    mat, bsdf = principled(bpy, name, base, 0.5, 0.5)
    tree = mat.node_tree
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    sep = tree.nodes.new("ShaderNodeSeparateColor")
    tree.links.new(tex.outputs["Color"], sep.inputs[0])
    tree.links.new(sep.outputs["Green"], bsdf.inputs["Roughness"])
    tree.links.new(sep.outputs["Blue"], bsdf.inputs["Metallic"])
    return mat, tex


def halves_image(bpy, name, left, right, size=SIZE):
    """A size x size float Non-Color image, grey `left` on u < 0.5 and `right` on the other half."""
    image = bpy.data.images.new(name, size, size, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"
    px = np.ones((size, size, 4), np.float32)
    px[:, : size // 2, :3] = left
    px[:, size // 2 :, :3] = right
    image.pixels.foreach_set(px.ravel())
    return image


def socket_material(bpy, name, image, socket, roughness=0.2):
    """A glossy white-ish dielectric whose `socket` (Specular IOR Level, IOR) is `image`'s Color (its luminance)."""
    material, bsdf = principled(bpy, name, roughness=roughness, metallic=0.0)
    tex = material.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    material.node_tree.links.new(tex.outputs["Color"], bsdf.inputs[socket])
    return material, bsdf


def id_material(bpy, image):
    """A Diffuse BSDF showing the quadrant colours (ID_COLOURS) of `image`."""
    mat = bpy.data.materials.new("ids")
    if mat.node_tree is None:
        mat.use_nodes = True
    tree = mat.node_tree
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    tex.interpolation = "Closest"
    tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def uv_sphere(bpy, order, segments=64, rings=32):
    """A UV sphere (radius 1, its UV map u around, v up) with an open bake (the clamped cosine)."""
    bpy.ops.mesh.primitive_uv_sphere_add(segments=segments, ring_count=rings, radius=1.0)
    obj = bpy.context.active_object
    obj.data.shade_smooth()
    normals = local_positions(obj.data)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    write_bake(obj, clamped_cosine_rows(normals, order), order)
    return obj


def quadrant_masks(image, erode=3):
    """Per quadrant the pixels of an ID render (id_material, diffuse, Closest: each pixel one
    quadrant's colour) in its colour (the dominant channel, or black), less `erode` pixels at the
    edges of each region (where a Linear map blends two quadrants)."""
    rgb = image[..., :3]
    covered = image[..., 3] > 0.99
    total = rgb.sum(axis=-1)
    masks = {}
    for q, colour in ID_COLOURS.items():
        if max(colour) == 0.0:
            mask = covered & (total < 1e-6)
        else:
            mask = covered & (rgb[..., int(np.argmax(colour))] > 0.999 * total) & (total > 1e-6)
        for _ in range(erode):
            mask = mask & np.roll(mask, 1, 0) & np.roll(mask, -1, 0) & np.roll(mask, 1, 1) & np.roll(mask, -1, 1)
        masks[q] = mask
    return masks
