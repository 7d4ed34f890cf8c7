"""Image-textured scenes: images written as sRGB PNGs, materials whose Base Color is an Image Texture."""

import os
import struct
import zlib

import numpy as np


def write_png(path, rgb):
    """Write (H, W, 3) uint8 sRGB values, top row first, as an 8-bit RGB PNG."""
    height, width = rgb.shape[:2]
    raw = b"".join(b"\x00" + np.ascontiguousarray(row, dtype=np.uint8).tobytes() for row in rgb)

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    with open(path, "wb") as f:
        f.write(
            b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")
        )
    return path


def halves_png(folder, size=8):
    """An image whose left half is pure red and right half pure blue."""
    rgb = np.zeros((size, size, 3), dtype=np.uint8)
    rgb[:, : size // 2, 0] = 255
    rgb[:, size // 2 :, 2] = 255
    return write_png(os.path.join(folder, "halves.png"), rgb)


CHECKER_COLOURS = np.array([[230, 40, 30], [40, 200, 60], [30, 60, 220], [240, 220, 40]], dtype=np.uint8)


def checker_png(folder, squares=4, texels=16):
    """squares x squares coloured checker squares (CHECKER_COLOURS in turn), texels per square."""
    i = np.arange(squares * texels) // texels
    index = (i[:, None] + 2 * (i[None, :] % 2) + i[None, :]) % len(CHECKER_COLOURS)
    return write_png(os.path.join(folder, "checker.png"), CHECKER_COLOURS[index])


def image_material(bpy, name, image, uv_map=None, multiply=None, shader="ShaderNodeBsdfPrincipled"):
    """A material whose diffuse colour is `image` (on the UV Map node's `uv_map` when given),
    times the colour `multiply` through a Multiply Mix node when given."""
    mat = bpy.data.materials.new(name)
    if mat.node_tree is None:  # Blender 4.x: new materials have no nodes
        mat.use_nodes = True
    tree = mat.node_tree
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    if shader != bsdf.bl_idname:
        tree.nodes.remove(bsdf)
        bsdf = tree.nodes.new(shader)
        out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
        tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
    socket = bsdf.inputs["Base Color" if shader == "ShaderNodeBsdfPrincipled" else "Color"]
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    if uv_map is not None:
        uv = tree.nodes.new("ShaderNodeUVMap")
        uv.uv_map = uv_map
        tree.links.new(uv.outputs["UV"], tex.inputs["Vector"])
    colour = tex.outputs["Color"]
    if multiply is not None:
        mix = tree.nodes.new("ShaderNodeMix")
        mix.data_type = "RGBA"
        mix.blend_type = "MULTIPLY"
        mix.inputs[0].default_value = 1.0
        mix.inputs[7].default_value = (*multiply, 1.0)
        tree.links.new(colour, mix.inputs[6])
        colour = mix.outputs[2]
    tree.links.new(colour, socket)
    return mat
