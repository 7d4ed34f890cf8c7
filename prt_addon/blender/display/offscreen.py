"""Render the camera view with the PRT shader offscreen to a numpy image, and save it as PNG.

`render_view` draws the same batches with the same shader and light buffers as the viewport draw
handler (draw_objects), into an RGBA32F GPUOffScreen with its own depth buffer. It draws
baked objects only (and the light markers when Display > Light Directions is on); the background
is transparent (alpha 0). The result is linear scene radiance times albedo (no exposure, no view
transform), row 0 at the top of the picture; or, with display=True, the display-referred image the
viewport overlay shows: exposure, the scene's display transform in the shader (colour.py), and the
way Blender turns overlay values into display code values (colour.encode_display).
"""

import bpy
import gpu
import numpy as np

from ..scene.lighting import exposure_scale
from ..world import nodes
from . import colour, light_markers
from .draw import baked_objects, draw_objects


def gpu_ready():
    """True when the gpu module can draw (in background mode only after initialisation)."""
    try:
        gpu.types.GPUOffScreen(4, 4)
    except Exception:  # "GPU functions for drawing are not available in background mode"
        return False
    return True


def ensure_gpu():
    """Initialise the GPU in background mode: gpu.init() where it exists, else
    one tiny Workbench render of a temporary scene. Returns True when the gpu module can draw."""
    if gpu_ready():
        return True
    init = getattr(gpu, "init", None)
    if init is not None:
        init()
        return gpu_ready()
    scene = bpy.data.scenes.new("prt_gpu_init")
    cam_data = bpy.data.cameras.new("prt_gpu_init")
    cam = bpy.data.objects.new("prt_gpu_init", cam_data)
    try:
        scene.collection.objects.link(cam)
        scene.camera = cam
        scene.render.engine = "BLENDER_WORKBENCH"
        scene.render.resolution_x = 8
        scene.render.resolution_y = 8
        bpy.ops.render.render(scene=scene.name)
    finally:
        bpy.data.objects.remove(cam)
        bpy.data.cameras.remove(cam_data)
        bpy.data.scenes.remove(scene)
    return gpu_ready()


def camera_matrices(scene, width, height, camera=None):
    """(view, projection) 4x4 numpy matrices of the scene camera for a width x height image."""
    camera = camera or scene.camera
    if camera is None:
        raise ValueError("the scene has no camera")
    depsgraph = bpy.context.evaluated_depsgraph_get()
    render = scene.render
    projection = camera.calc_matrix_camera(
        depsgraph, x=width, y=height, scale_x=render.pixel_aspect_x, scale_y=render.pixel_aspect_y
    )
    view = camera.matrix_world.inverted()
    return np.array(view, dtype=np.float64), np.array(projection, dtype=np.float64)


def render_size(scene):
    pct = scene.render.resolution_percentage / 100.0
    return max(1, int(scene.render.resolution_x * pct)), max(1, int(scene.render.resolution_y * pct))


def render_view(scene=None, width=None, height=None, camera=None, objects=None, scale=1.0, display=False):
    """(H, W, 4) float32 image of the baked objects seen by the camera, top row first.

    width/height default to the scene's render size; objects default to the visible baked
    objects of the first view layer; scale multiplies the radiance (e.g. lighting.exposure_scale).
    display=False: linear radiance. display=True: as the viewport overlay draws it, the radiance
    times 2**exposure through the scene's display transform, as display code values (0..1, not
    quantised).
    """
    scene = scene or bpy.context.scene
    if width is None or height is None:
        width, height = render_size(scene)
    if not ensure_gpu():
        raise RuntimeError("the gpu module cannot draw in this session")
    view, projection = camera_matrices(scene, width, height, camera)
    # Deformed objects as the context's depsgraph evaluates them (another scene's: undeformed).
    depsgraph = bpy.context.evaluated_depsgraph_get() if scene == bpy.context.scene else None
    if objects is None:
        view_layer = bpy.context.view_layer if scene == bpy.context.scene else scene.view_layers[0]
        objects = baked_objects(scene, view_layer)
    lut = None
    if display:
        scale = scale * exposure_scale(scene)
        lut = colour.texture(scene, build=True)
    offscreen = gpu.types.GPUOffScreen(width, height, format="RGBA32F")
    try:
        with offscreen.bind():
            fb = gpu.state.active_framebuffer_get()
            fb.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
            gpu.state.depth_test_set("LESS_EQUAL")
            gpu.state.depth_mask_set(True)
            try:
                draw_objects(scene, projection @ view, objects, scale=scale, depsgraph=depsgraph, display_lut=lut)
            finally:
                gpu.state.depth_test_set("NONE")
            if light_markers.enabled(scene):
                light_markers.draw_markers(scene, view, projection, (width, height))
        # Read from the texture, not the framebuffer: the shadow maps' and texel relights' own
        # framebuffers, bound while drawing, can leave this one unbound ("Framebuffer is not
        # bound" when the lights' maps were rebuilt, as right after a bake). The buffer's numpy
        # view has reversed strides: transpose, then reshape.
        image = np.asarray(offscreen.texture_color.read()).T.reshape(height, width, 4).copy()
    finally:
        offscreen.free()
    image = image[::-1].copy()
    if display:  # the code values Blender's display shader makes of the overlay's values
        image[..., :3] = colour.encode_display(image[..., :3])
    return image


def save_png(image, path, scene=None, background=None):
    """Write an (H, W, 4) linear float image (top row first) as PNG with the scene's colour
    management (view transform, look, exposure, gamma: Image.save_render).

    background: optional linear RGB composited under the image's alpha.
    """
    scene = scene or bpy.context.scene
    img = np.asarray(image, dtype=np.float32)
    height, width = img.shape[:2]
    if background is not None:
        alpha = img[..., 3:4]
        rgb = img[..., :3] + (1.0 - alpha) * np.asarray(background, dtype=np.float32)[:3]
        img = np.concatenate([rgb, np.ones_like(alpha)], axis=-1)
    target = bpy.data.images.new("prt_save_png", width, height, alpha=True, float_buffer=True)
    try:
        target.pixels.foreach_set(np.ascontiguousarray(img[::-1]).reshape(-1))
        settings = scene.render.image_settings
        old = (settings.file_format, settings.color_mode, settings.color_depth)
        settings.file_format = "PNG"
        settings.color_mode = "RGBA"
        settings.color_depth = "8"
        try:
            target.save_render(path, scene=scene)
        finally:
            settings.file_format, settings.color_mode, settings.color_depth = old
    finally:
        bpy.data.images.remove(target)
    return path


def render_rotations(scene, angles_deg, path_pattern, width=None, height=None, background=None):
    """Render the PRT view at several lighting rotations about Z (through the world's Mapping
    node, as the sidebar does) and save each as PNG; path_pattern gets the angle ("{:03d}").
    The Mapping rotation is restored afterwards. Returns the list of paths."""
    old = nodes.mapping_rotation_euler(scene.world)
    paths = []
    try:
        for angle in angles_deg:
            rot = (old[0], old[1], np.radians(angle))
            if not nodes.set_mapping_rotation_euler(scene.world, rot):
                raise ValueError("the world has no Environment Texture to rotate")
            image = render_view(scene, width, height)
            paths.append(save_png(image, path_pattern.format(int(round(angle))), scene, background))
    finally:
        if nodes.find_mapping_node(scene.world) is not None:
            nodes.set_mapping_rotation_euler(scene.world, old)
    return paths
