"""Textured scenes for the web plugin: a baked ground whose Principled Base Color is an Image Texture of a PNG, and where each pixel of a camera looking down lands on it."""

import numpy as np

from helpers.worlds import bundled_hdri_path, new_world, use_image
from prt_addon.core.ibl.rgbd_png import png_bytes

# sRGB bytes of the four quadrants, (row, column) of the picture from its top left.
QUADRANTS = {(0, 0): (230, 40, 30), (0, 1): (30, 80, 220), (1, 0): (40, 200, 60), (1, 1): (250, 220, 40)}
TEXTURE_SIZE = 64
GROUND = 2.0  # the ground's side (Blender units, centred on the origin, UV 0..1 across it)
BOX = ((0.2, 0.2, 0.0), (0.7, 0.7, 0.5))  # the untextured box on the ground (Blender frame, min and max)
PAINT = (0.3, 0.6, 0.9)  # the box's colour attribute (linear), used by its material in the painted file
# A perspective camera straight down (glTF frame: position, target; vertical field of view in degrees).
CAMERA = {"fov": 40.0, "position": [0.0, 3.0, 1e-4], "target": [0.0, 0.0, 0.0]}


def srgb_to_linear(c):
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def quadrant_png(path, white=False):
    """The texture (TEXTURE_SIZE square, four quadrants of QUADRANTS, or all white) as a PNG."""
    half = TEXTURE_SIZE // 2
    rgba = np.full((TEXTURE_SIZE, TEXTURE_SIZE, 4), 255, np.uint8)
    if not white:
        for (row, col), rgb in QUADRANTS.items():
            rgba[row * half : (row + 1) * half, col * half : (col + 1) * half, :3] = rgb
    path.write_bytes(png_bytes(rgba))
    return str(path)


def _material(bpy, name, image=None, base=(0.8, 0.8, 0.8)):
    mat = bpy.data.materials.new(name)
    if mat.node_tree is None:
        mat.use_nodes = True
    tree = mat.node_tree
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (*base, 1.0)
    bsdf.inputs["Roughness"].default_value = 1.0
    if image is not None:
        tex = tree.nodes.new("ShaderNodeTexImage")
        tex.image = image
        tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def textured_scene(bpy, scene, png):
    """A 24 x 24 grid ground (GROUND) textured with the PNG at `png`, an untextured grey box on it
    (with a colour attribute of PAINT, unused by its material), under forest.exr; -> (ground, box,
    the ground's material's Image Texture node)."""
    world = new_world(bpy, scene)
    use_image(world, bpy.data.images.load(bundled_hdri_path("forest"), check_existing=True))
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=24, y_subdivisions=24, size=GROUND)
    ground = bpy.context.active_object
    ground.name = "TexturedGround"
    ground.data.materials.append(_material(bpy, "textured", bpy.data.images.load(png)))
    lo, hi = np.array(BOX[0]), np.array(BOX[1])
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=tuple((lo + hi) / 2))
    box = bpy.context.active_object
    box.name = "Box"
    box.scale = tuple(hi - lo)
    bpy.ops.object.transform_apply(scale=True)
    box.data.materials.append(_material(bpy, "grey", base=(0.6, 0.6, 0.6)))
    paint = box.data.color_attributes.new("Paint", "FLOAT_COLOR", "POINT")
    paint.data.foreach_set("color", np.tile(np.array([*PAINT, 1.0], np.float32), len(box.data.vertices)))
    tex = next(n for n in ground.data.materials[0].node_tree.nodes if n.bl_idname == "ShaderNodeTexImage")
    return ground, box, tex


def _rays(width, height):
    """Per pixel (top row first) the camera's origin and ray direction, in Blender's frame."""
    pos, target = np.array(CAMERA["position"]), np.array(CAMERA["target"])
    back = (pos - target) / np.linalg.norm(pos - target)  # three.js's lookAt, up +Y
    right = np.cross([0.0, 1.0, 0.0], back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    t = np.tan(np.radians(CAMERA["fov"]) / 2)
    x = ((np.arange(width) + 0.5) / width * 2 - 1) * t * width / height
    y = (1 - (np.arange(height) + 0.5) / height * 2) * t
    d = x[None, :, None] * right + y[:, None, None] * up - back
    to_blender = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # glTF (x, y, z) -> Blender (x, -z, y)
    return to_blender @ pos, d @ to_blender.T


def pixel_map(width, height):
    """Per pixel: the ground's UV where the ray lands (nan off it), and whether the box is hit first."""
    origin, d = _rays(width, height)
    s = -origin[2] / d[..., 2]
    hit = origin[:2] + s[..., None] * d[..., :2]
    uv = hit / GROUND + 0.5
    uv[~np.all((uv >= 0) & (uv <= 1), axis=-1)] = np.nan
    lo, hi = np.array(BOX[0]), np.array(BOX[1])
    with np.errstate(divide="ignore", invalid="ignore"):
        a, b = (lo - origin) / d, (hi - origin) / d
    near = np.minimum(a, b).max(axis=-1)
    far = np.maximum(a, b).min(axis=-1)
    return uv, (near <= far) & (far > 0)


def texture_colour(uv, offset=(0.0, 0.0)):
    """The texture's linear colour at UV (Blender's: v up, the picture's row 0 at v = 1), the
    lookup moved by `offset` (wrapping), and the distance in texels to the nearest quadrant edge."""
    u = np.mod(uv[..., 0] + offset[0], 1.0)
    v = np.mod(uv[..., 1] + offset[1], 1.0)
    row = (v < 0.5).astype(int)  # v < 0.5: the picture's bottom half
    col = (u >= 0.5).astype(int)
    colours = np.zeros(uv.shape[:-1] + (3,))
    for (r, c), rgb in QUADRANTS.items():
        colours[(row == r) & (col == c)] = srgb_to_linear(np.array(rgb) / 255)
    edge = np.minimum.reduce([np.abs(u - 0.5), np.abs(v - 0.5), u, 1 - u, v, 1 - v]) * TEXTURE_SIZE
    return colours, edge


def paint_box(bpy, box):
    """Feed the box's Principled Base Color from its colour attribute (Blender's exporter then
    writes it as COLOR_0, base colour factor 1)."""
    tree = box.data.materials[0].node_tree
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    node = tree.nodes.new("ShaderNodeVertexColor")
    node.layer_name = "Paint"
    tree.links.new(node.outputs["Color"], bsdf.inputs["Base Color"])


GLOSSY = {"r0.3_m0": (0.3, 0.0), "r0.6_m0": (0.6, 0.0), "r0.3_m1": (0.3, 1.0), "r0.6_m1": (0.6, 1.0)}


def glossy_scene(bpy, scene, hdri="forest"):
    """Four Principled spheres (radius 0.45; GLOSSY's roughness and metallic, base 0.8) in a row on
    a 6 x 6 ground (roughness 1), the camera looking down at them, the scene's Specular on;
    -> ({name: object} with the ground, camera)."""
    from helpers.display_scenes import add_camera
    from helpers.specular_scenes import principled_material

    scene.prt_display.specular = True
    world = new_world(bpy, scene)
    use_image(world, bpy.data.images.load(bundled_hdri_path(hdri), check_existing=True))
    objects = {}
    for i, (name, (roughness, metallic)) in enumerate(GLOSSY.items()):
        bpy.ops.mesh.primitive_uv_sphere_add(
            segments=48, ring_count=24, radius=0.45, location=(1.1 * i - 1.65, 0, 0.45)
        )
        obj = bpy.context.active_object
        obj.name = name
        obj.data.shade_smooth()
        obj.data.materials.append(principled_material(bpy, name, (0.8, 0.8, 0.8), roughness, metallic))
        objects[name] = obj
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=48, y_subdivisions=48, size=6.0)
    ground = bpy.context.active_object
    ground.name = "ground"
    ground.data.materials.append(principled_material(bpy, "ground", (0.5, 0.5, 0.5), 1.0, 0.0))
    objects["ground"] = ground
    cam = add_camera(bpy, scene, location=(0.0, -4.2, 2.6), euler=(np.radians(60.0), 0.0, 0.0), size=320)
    scene.render.resolution_y = 160
    bpy.context.view_layer.update()
    return objects, cam
