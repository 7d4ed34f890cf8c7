"""A glossy texel-baked floor (one quad) with a box standing on it under a sunny HDRI, the camera low in front: the floor before the box's foot mirrors the box, not the sky."""

import contextlib
import math

import numpy as np

from helpers.display_scenes import add_camera
from helpers.specular_scenes import principled_material
from helpers.texel_scenes import lightmap_unwrap
from helpers.worlds import bundled_hdri_path, new_world, use_image

BOX_FRONT = -0.1  # the box's face toward the camera (y)
SIZE = (160, 96)


def glossy_floor_scene(bpy, scene, roughness, metallic=1.0, hdri="city"):
    """A 4 x 4 m floor quad (its UVMap: u = x / 4 + 1/2) of a Principled material, a 0.8 m box on
    it (Smart UV lightmap), the camera 1.1 m high 3 m before it; -> (floor, box, camera)."""
    scene.prt_display.specular = True
    world = new_world(bpy, scene)
    use_image(world, bpy.data.images.load(bundled_hdri_path(hdri), check_existing=True))
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    floor = bpy.context.object
    floor.name = "Floor"
    floor.data.materials.append(principled_material(bpy, "floor", (0.8, 0.8, 0.8), roughness, metallic))
    bpy.ops.mesh.primitive_cube_add(size=0.8, location=(0.0, BOX_FRONT + 0.4, 0.4))
    box = bpy.context.object
    box.name = "Box"
    box.data.materials.append(principled_material(bpy, "box", (0.5, 0.5, 0.5), 1.0, 0.0))
    lightmap_unwrap(bpy, box)
    target = np.array([0.0, 0.0, 0.0])
    eye = np.array([0.0, -3.0, 1.1])
    pitch = math.atan2(eye[2] - target[2], target[1] - eye[1])
    cam = add_camera(bpy, scene, location=tuple(eye), euler=(math.pi / 2 - pitch, 0.0, 0.0), size=SIZE[0])
    cam.data.lens = 35.0
    scene.render.resolution_y = SIZE[1]
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    bpy.context.view_layer.update()
    return floor, box, cam


def floor_region_mask(bpy, scene, y_range, x_half=0.5, size=SIZE):
    """(H, W) bool, top row first: the pixels that see the floor's points with y in y_range and
    |x| < x_half (projected through the scene camera; pixels the box hides are the caller's to drop)."""
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector

    mask = np.zeros((size[1], size[0]), dtype=bool)
    for x in np.linspace(-x_half, x_half, 200):
        for y in np.linspace(y_range[0], y_range[1], 200):
            p = world_to_camera_view(scene, scene.camera, Vector((x, y, 0.0)))
            i, j = int(p.x * size[0]), int((1.0 - p.y) * size[1])
            if 0 <= i < size[0] and 0 <= j < size[1]:
                mask[j, i] = True
    return mask


@contextlib.contextmanager
def without_texel_occlusion():
    """Texel bakes drawn as before they had a specular occlusion (the open transfer: 1), inside."""
    from prt_addon.blender.display import shader, texel_occlusion

    original = texel_occlusion.add_occlusion

    def unoccluded(info, fragment, count, back):
        info.sampler(texel_occlusion.TILES_SLOT, "FLOAT_2D", "texel_tiles_tx")  # (bound by draw.py)
        return fragment

    texel_occlusion.add_occlusion = unoccluded
    shader.clear_shaders()
    try:
        yield
    finally:
        texel_occlusion.add_occlusion = original
        shader.clear_shaders()
