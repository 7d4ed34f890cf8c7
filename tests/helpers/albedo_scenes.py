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


def box_uvs(mesh):
    """Set the first UV map to a box mapping: each corner's face, by its normal's main axis, shows
    the whole 0..1 square over the box's unit side (the other two coordinates + 0.5)."""
    n_faces = len(mesh.polygons)
    normals = np.empty(3 * n_faces, dtype=np.float32)
    mesh.polygons.foreach_get("normal", normals)
    starts = np.empty(n_faces, dtype=np.int32)
    mesh.polygons.foreach_get("loop_start", starts)
    sizes = np.diff(starts, append=np.int32(len(mesh.loops)))
    axis = np.repeat(np.argmax(np.abs(normals.reshape(-1, 3)), axis=1), sizes)
    verts = np.empty(len(mesh.loops), dtype=np.int32)
    mesh.loops.foreach_get("vertex_index", verts)
    co = np.empty(3 * len(mesh.vertices), dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    p = co.reshape(-1, 3)[verts]
    pairs = np.array([[1, 2], [0, 2], [0, 1]])[axis]
    uv = np.take_along_axis(p, pairs, axis=1) + 0.5
    if len(mesh.uv_layers) == 0:
        mesh.uv_layers.new(name="UVMap")
    mesh.uv_layers[0].data.foreach_set("uv", uv.astype(np.float32).ravel())


def textured_box_scene(bpy, scene, folder, hdri="city", size=(160, 120)):
    """A unit box (subdivided, flat, box-mapped 4 x 4 checker of CHECKER_COLOURS on each side) on an
    8 x 8 grey ground under a bundled HDRI, the camera looking down at two of its sides and its top;
    -> (box, ground)."""
    import bmesh
    import mathutils

    from helpers.display_scenes import add_camera
    from helpers.specular_scenes import principled_material
    from helpers.worlds import bundled_hdri_path, new_world, use_image

    world = new_world(bpy, scene)
    use_image(world, bpy.data.images.load(bundled_hdri_path(hdri), check_existing=True))
    mesh = bpy.data.meshes.new("box")
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=1.0)
    bmesh.ops.subdivide_edges(bm, edges=bm.edges[:], cuts=7, use_grid_fill=True)
    bm.to_mesh(mesh)
    bm.free()
    box_uvs(mesh)
    box = bpy.data.objects.new("box", mesh)
    scene.collection.objects.link(box)
    box.location = (0.0, 0.0, 0.5)
    image = bpy.data.images.load(checker_png(folder))
    mesh.materials.append(image_material(bpy, "checker", image))
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=48, y_subdivisions=48, size=8.0)
    ground = bpy.context.active_object
    ground.name = "ground"
    ground.data.materials.append(principled_material(bpy, "ground", (0.5, 0.5, 0.5), 1.0, 0.0))
    eye = mathutils.Vector((2.4, -3.2, 2.6))
    rotation = (mathutils.Vector((0.0, 0.0, 0.45)) - eye).to_track_quat("-Z", "Y").to_euler()
    add_camera(bpy, scene, location=tuple(eye), euler=tuple(rotation), size=size[0])
    scene.render.resolution_y = size[1]
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    bpy.context.view_layer.update()
    return box, ground


def expected_halves(u, extension):
    """The halves image (red for u in [0, 0.5), blue in [0.5, 1)) at u, away from texel edges, as
    the Image Texture node's extension continues it outside [0, 1]; None: black (Clip)."""
    half = np.floor(u / 0.5).astype(int)  # which half-image-wide strip u is in
    if extension == "REPEAT":
        red = half % 2 == 0
    elif extension == "EXTEND":
        red = np.where(half < 0, True, np.where(half >= 2, False, half == 0))
    elif extension == "CLIP":
        red = half % 2 == 0
    else:  # MIRROR: u -> u mod 2, folded back above 1
        folded = np.mod(u, 2.0)
        red = np.where(folded > 1.0, 2.0 - folded, folded) < 0.5
    colour = np.where(red[:, None], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    if extension == "CLIP":
        colour[(half < 0) | (half >= 2)] = 0.0
    return colour
