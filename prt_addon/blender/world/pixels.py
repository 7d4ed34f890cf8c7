"""Pixels of the world: an image's scene-linear pixels, or the world rendered by Cycles."""

import math
import os
import shutil
import tempfile

import bpy
import mathutils
import numpy as np

from ...core.sh import resample
from .nodes import WorldError

# Camera rotation that makes a Cycles equirectangular panorama equal Blender's equirect convention
# (measured: rendering an Environment Texture with this camera reproduces the image to 2e-7).
PANORAMA_CAMERA_EULER = (math.pi / 2.0, 0.0, -math.pi / 2.0)


RENDER_SAMPLES = 16


# 8-bit images store encoded values k/255; these colour spaces are converted exactly with
# Blender's own OCIO conversion (mathutils.Color), tabulated once per channel. Others are rendered.
_BYTE_CONVERSIONS = {
    "sRGB": "from_srgb_to_scene_linear",
    "Linear Rec.709": "from_rec709_linear_to_scene_linear",
    "Linear Rec.2020": "from_rec2020_linear_to_scene_linear",
    "ACEScg": "from_acescg_to_scene_linear",
    "ACES2065-1": "from_aces_to_scene_linear",
    "Linear CIE-XYZ D65": "from_xyz_d65_to_scene_linear",
}


_RAW_COLORSPACES = ("Non-Color", "scene_linear")


class NeedsRender(Exception):
    """Internal: the direct path cannot represent this world exactly; render it instead."""


def _image_path(image):
    try:
        return bpy.path.abspath(image.filepath, library=image.library)
    except Exception:
        return image.filepath


def _byte_lut(method_name):
    """(256, 3, 3) table: lut[k, a] = scene-linear RGB of the encoded colour k/255 on channel a.

    Exact for conversions made of a per-channel curve followed by a 3x3 matrix (every entry of
    _BYTE_CONVERSIONS), which is the case because conversion(v e_a) sums over channels a.
    """
    lut = np.empty((256, 3, 3))
    for k in range(256):
        v = k / 255.0
        for a in range(3):
            rgb = [0.0, 0.0, 0.0]
            rgb[a] = v
            lut[k, a] = tuple(getattr(mathutils.Color(rgb), method_name)())
    return lut


def read_image_pixels(image):
    """(H, W, C) float32 scene-linear pixels of an image, row 0 at the bottom.

    Float images: Image.pixels is already scene linear (Blender converts float buffers on load;
    measured equal to what Cycles renders for every colour space). 8-bit images: Image.pixels
    holds the encoded values k/255; they are converted with Blender's own conversion (see
    _BYTE_CONVERSIONS), or NeedsRender is raised for other colour spaces.
    """
    width, height = (int(v) for v in image.size)
    if width * height == 0 or not image.has_data:
        if image.source == "FILE" and image.packed_file is None:
            path = _image_path(image)
            if not os.path.isfile(path):
                raise WorldError(f"Image '{image.name}' could not be loaded: file '{path}' not found")
        raise WorldError(f"Image '{image.name}' could not be loaded (no pixels)")
    channels = int(image.channels)
    buffer = np.empty(width * height * channels, dtype=np.float32)
    image.pixels.foreach_get(buffer)
    pixels = buffer.reshape(height, width, channels)
    colorspace = image.colorspace_settings.name
    if image.is_float or image.colorspace_settings.is_data or colorspace in _RAW_COLORSPACES:
        return pixels
    method = _BYTE_CONVERSIONS.get(colorspace)
    if method is None:
        raise NeedsRender(f"8-bit image '{image.name}' is in colour space '{colorspace}'")
    if channels < 3:
        pixels = np.repeat(pixels[:, :, :1], 3, axis=2)
        channels = 3
    lut = _byte_lut(method).astype(np.float32)
    for start in range(0, height, resample.ROW_BLOCK):
        rows = pixels[start : start + resample.ROW_BLOCK, :, :3]
        index = np.clip(np.rint(rows * 255.0), 0, 255).astype(np.uint8)
        converted = lut[index[..., 0], 0] + lut[index[..., 1], 1] + lut[index[..., 2], 2]
        pixels[start : start + resample.ROW_BLOCK, :, :3] = converted
    return pixels


def render_world(scene, height):
    """Render scene.world with Cycles to an (height, 2 height, 3) float32 scene-linear equirect.

    A temporary scene with no objects holds a copy of the world (so camera visibility can be forced
    on without touching the user's world) and a panoramic camera; everything is removed afterwards.
    """
    world = scene.world
    height = max(1, int(height))
    folder = tempfile.mkdtemp(prefix="prt_world_")
    temp_scene = world_copy = camera_data = camera = image = None
    try:
        world_copy = world.copy()
        if hasattr(world_copy, "visibility_camera"):
            world_copy.visibility_camera = True
        elif hasattr(world_copy, "cycles_visibility"):
            world_copy.cycles_visibility.camera = True
        temp_scene = bpy.data.scenes.new("PRT world render")
        temp_scene.world = world_copy
        temp_scene.frame_current = scene.frame_current
        camera_data = bpy.data.cameras.new("PRT world panorama")
        camera_data.type = "PANO"
        camera_data.panorama_type = "EQUIRECTANGULAR"
        camera = bpy.data.objects.new("PRT world panorama", camera_data)
        camera.rotation_euler = PANORAMA_CAMERA_EULER
        temp_scene.collection.objects.link(camera)
        temp_scene.camera = camera
        render = temp_scene.render
        render.engine = "CYCLES"
        render.resolution_x = 2 * height
        render.resolution_y = height
        render.resolution_percentage = 100
        render.film_transparent = False
        render.use_compositing = False
        render.use_sequencer = False
        render.image_settings.file_format = "OPEN_EXR"
        render.image_settings.color_depth = "32"
        render.filepath = os.path.join(folder, "world.exr")
        cycles = temp_scene.cycles
        cycles.device = "CPU"
        cycles.samples = RENDER_SAMPLES
        cycles.use_denoising = False
        cycles.use_adaptive_sampling = False
        # A unit box filter averages each pixel, which is what the per-pixel projection assumes.
        cycles.pixel_filter_type = "BOX"
        cycles.filter_width = 1.0
        bpy.ops.render.render(write_still=True, scene=temp_scene.name)
        path = render.filepath
        if not os.path.isfile(path):
            raise WorldError("Cycles did not write the rendered world image")
        image = bpy.data.images.load(path)
        w, h = image.size
        buffer = np.empty(w * h * image.channels, dtype=np.float32)
        image.pixels.foreach_get(buffer)
        return buffer.reshape(h, w, image.channels)[:, :, :3]
    finally:
        if image is not None:
            bpy.data.images.remove(image)
        if temp_scene is not None:
            bpy.data.scenes.remove(temp_scene)
        if camera is not None:
            bpy.data.objects.remove(camera)
        if camera_data is not None:
            bpy.data.cameras.remove(camera_data)
        if world_copy is not None:
            bpy.data.worlds.remove(world_copy)
        shutil.rmtree(folder, ignore_errors=True)
