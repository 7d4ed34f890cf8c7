"""Read the scene's World and turn it into RGB SH lighting (issue 3); see docs/world.md.

Recognised node trees are read directly:

    [Texture Coordinate.Generated -> Mapping ->] Environment Texture.Color -> Background.Color
    constant colour -> Background.Color

with the Background strength a constant. The Mapping node's rotation is not applied to the pixels:
the image is projected in its own frame and the coefficients are rotated (stored unrotated, so a
rotation change needs no new projection, see current_world_coeffs). Any other world (Sky Texture,
gradients, mixes, 8-bit images in unusual colour spaces, a Mapping location or a non-uniform
scale) is rendered by Cycles to an equirectangular image with a panoramic camera in a temporary
scene without objects, and that image is projected.

Measured against Cycles (tests/test_world_cycles.py): with a Mapping rotation R (Euler XYZ,
R = Rz Ry Rx), the world seen along D is image(R D) for vector types POINT, VECTOR and NORMAL and
image(R^-1 D) for TEXTURE; so world coefficients = rotate(image coefficients, Q) with Q = R^T
(POINT, VECTOR, NORMAL) or Q = R (TEXTURE), since rotate(c, Q) gives f(Q^-1 w).
"""

import math
import os
import shutil
import tempfile
import time
import uuid
import warnings
from dataclasses import dataclass, field

import bpy
import mathutils
import numpy as np

from ..core import projection, resample, rotation, sh

SH_KEY = "prt_world_sh"  # unrotated (image-frame) coefficients, flat, index 3 * i + channel
SH_WORLD_KEY = "prt_world_sh_world"  # world-space coefficients as projected (rotation applied)

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


MAX_ORDER = 32  # the Order property's maximum; (order**2, 3) coefficients


class WorldError(ValueError):
    """The world cannot be projected; the message is meant for the user."""


class _NeedsRender(Exception):
    """Internal: the direct path cannot represent this world exactly; render it instead."""


@dataclass
class MappingInfo:
    node_name: str
    vector_type: str
    euler: tuple

    def sh_rotation(self):
        return mapping_sh_rotation(self.vector_type, self.euler)


@dataclass
class WorldSource:
    kind: str  # "IMAGE", "COLOR" or "RENDER"
    world_name: str
    node_name: str = ""
    image: object = None
    color: object = None
    strength: float = 1.0
    mapping: MappingInfo = None
    reason: str = ""


@dataclass
class WorldProjection:
    order: int
    image_coeffs: np.ndarray  # (n*n, 3) in the image's own frame (Mapping rotation not applied)
    rotation: np.ndarray  # 3x3 Q: coeffs = rotation.rotate(image_coeffs, Q)
    coeffs: np.ndarray  # (n*n, 3) world space
    source: WorldSource
    seconds: float = 0.0
    truncation: float = 0.0
    diffuse_truncation: float = 0.0
    source_size: tuple = (0, 0)  # image (width, height) read or rendered
    projected_size: tuple = (0, 0)  # after reduction
    warnings: list = field(default_factory=list)


def mapping_sh_rotation(vector_type, euler):
    """Q such that world coefficients = rotation.rotate(image coefficients, Q) (measured)."""
    r = rotation.euler_xyz_matrix(euler)
    return r if vector_type == "TEXTURE" else r.T


# --- reading the node tree -------------------------------------------------------------------


def _from_link(socket):
    """The link feeding `socket`, through reroutes; None if unlinked or muted."""
    while socket.is_linked:
        link = socket.links[0]
        if link.is_muted or not link.is_valid:
            return None
        node = link.from_node
        if node.bl_idname == "NodeReroute":
            socket = node.inputs[0]
            continue
        return link
    return None


def _use_nodes(world):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return bool(world.use_nodes) and world.node_tree is not None


def _render_source(world, node, reason):
    return WorldSource("RENDER", world.name, node_name=node.name if node else "", reason=reason)


def _mapping_info(world, env, link):
    """MappingInfo of a Mapping node feeding env's Vector, or a RENDER source if unrepresentable."""
    mapping = link.from_node
    if mapping.bl_idname != "ShaderNodeMapping" or mapping.mute:
        return _render_source(world, env, f"the Vector of '{env.name}' comes from '{link.from_node.name}'")
    source = _from_link(mapping.inputs["Vector"])
    if (
        source is None
        or source.from_node.bl_idname != "ShaderNodeTexCoord"
        or source.from_socket.identifier != "Generated"
    ):
        return _render_source(
            world, env, f"the Mapping node '{mapping.name}' is not fed by Texture Coordinate > Generated"
        )
    vector_type = mapping.vector_type
    sockets = {s.name: s for s in mapping.inputs}
    for name in ("Location", "Rotation", "Scale"):
        if name in sockets and sockets[name].enabled and _from_link(sockets[name]) is not None:
            return _render_source(world, env, f"the {name} of Mapping node '{mapping.name}' is linked")
    problems = []
    if vector_type in ("POINT", "TEXTURE"):
        location = np.array(sockets["Location"].default_value, dtype=np.float64)
        if np.any(location != 0.0):
            problems.append(f"location {tuple(np.round(location, 4))}")
    scale = np.array(sockets["Scale"].default_value, dtype=np.float64)
    # The Environment Texture normalises its vector, so a uniform positive scale changes nothing.
    if not (np.all(scale > 0.0) and np.ptp(scale) <= 1e-6 * scale.max()):
        problems.append(f"scale {tuple(np.round(scale, 4))}")
    if problems:
        return _render_source(
            world,
            env,
            f"the Mapping node '{mapping.name}' has a {' and a '.join(problems)} that an SH rotation "
            "cannot represent",
        )
    euler = tuple(float(a) for a in sockets["Rotation"].default_value)
    return MappingInfo(mapping.name, vector_type, euler)


def analyse_world(scene):
    """What the scene's world is made of: a WorldSource, or WorldError if there is no light."""
    world = scene.world
    if world is None:
        raise WorldError(f"Scene '{scene.name}' has no World: add one in the World properties")
    if not _use_nodes(world):
        color = np.array(world.color, dtype=np.float64)[:3]
        return WorldSource("COLOR", world.name, color=color)
    tree = world.node_tree
    output = tree.get_output_node("CYCLES")
    if output is None:
        raise WorldError(f"World '{world.name}' has no active World Output node: it emits no light")
    link = _from_link(output.inputs["Surface"])
    if link is None:
        raise WorldError(f"Nothing is connected to the Surface of World '{world.name}': it emits no light")
    background = link.from_node
    if background.bl_idname != "ShaderNodeBackground" or background.mute:
        return _render_source(world, background, f"the world surface is '{background.name}', not a Background")
    if _from_link(background.inputs["Strength"]) is not None:
        return _render_source(world, background, f"the Strength of '{background.name}' is linked")
    strength = float(background.inputs["Strength"].default_value)
    if not math.isfinite(strength) or strength < 0.0:
        raise WorldError(f"Background '{background.name}' has a strength of {strength}: it must be >= 0")
    color_link = _from_link(background.inputs["Color"])
    if color_link is None:
        color = np.array(background.inputs["Color"].default_value, dtype=np.float64)[:3]
        return WorldSource("COLOR", world.name, node_name=background.name, color=color, strength=strength)
    env = color_link.from_node
    if (
        env.bl_idname != "ShaderNodeTexEnvironment"
        or env.mute
        or color_link.from_socket.identifier != "Color"
        or env.projection != "EQUIRECTANGULAR"
    ):
        return _render_source(world, env, f"the Background colour comes from '{env.name}'")
    if env.image is None:
        raise WorldError(f"Environment Texture '{env.name}' has no image")
    if env.image.source not in ("FILE", "GENERATED"):
        return _render_source(world, env, f"image '{env.image.name}' is a {env.image.source.lower()}")
    mapping = None
    vector_link = _from_link(env.inputs["Vector"])
    if vector_link is not None:
        if vector_link.from_node.bl_idname == "ShaderNodeTexCoord":
            if vector_link.from_socket.identifier != "Generated":
                return _render_source(world, env, f"the Vector of '{env.name}' is not Generated coordinates")
        else:
            mapping = _mapping_info(world, env, vector_link)
            if isinstance(mapping, WorldSource):
                return mapping
    return WorldSource(
        "IMAGE", world.name, node_name=env.name, image=env.image, strength=strength, mapping=mapping
    )


# --- reading pixels ---------------------------------------------------------------------------


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
    _BYTE_CONVERSIONS), or _NeedsRender is raised for other colour spaces.
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
        raise _NeedsRender(f"8-bit image '{image.name}' is in colour space '{colorspace}'")
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


def project_pixels(pixels, order):
    """(coeffs, report, energy, projected (w, h), diffuse truncation) of an equirect image reduced
    to what order needs. It is projected once at max(order, 32): the first order**2 coefficients
    are the same, and the higher bands measure what diffuse shading loses beyond the order."""
    height, width = pixels.shape[:2]
    h_out, w_out = resample.target_size(height, width, order)
    reduced, report, energy = resample.reduce_equirect(pixels, h_out, w_out)
    reference, _ = projection.project_equirect(reduced, max(order, resample.DIFFUSE_REFERENCE_ORDER))
    diffuse_truncation = resample.diffuse_truncation_fraction(reference, order)
    return reference[: order * order].copy(), report, energy, (w_out, h_out), diffuse_truncation


# --- the projection ---------------------------------------------------------------------------


def project(scene, order, force_render=False):
    """Project scene.world: a WorldProjection (nothing is stored). Raises WorldError."""
    try:
        order = sh.check_order(order)
    except ValueError as error:
        raise WorldError(str(error)) from None
    start = time.perf_counter()
    source = analyse_world(scene)
    notes = []
    if force_render and source.kind != "RENDER":
        source = _render_source(scene.world, None, "a render was requested")
    pixels = None
    if source.kind == "IMAGE":
        try:
            pixels = read_image_pixels(source.image)
        except _NeedsRender as why:
            source = _render_source(scene.world, None, str(why))
    truncation = diffuse_truncation = 0.0
    source_size = projected_size = (0, 0)
    if source.kind == "COLOR":
        color = np.asarray(source.color, dtype=np.float64) * source.strength
        if not np.all(np.isfinite(color)):
            raise WorldError(f"World '{source.world_name}' has a non-finite colour {tuple(color)}")
        if np.any(color < 0.0):
            notes.append(f"negative background colour {tuple(np.round(color, 6))} clamped to 0")
            color = np.clip(color, 0.0, None)
        image_coeffs = np.zeros((order * order, 3))
        image_coeffs[0] = np.sqrt(4.0 * np.pi) * color
    else:
        if source.kind == "RENDER":
            notes.append(f"world rendered with Cycles because {source.reason}")
            pixels = render_world(scene, resample.needed_height(order))
        source_size = (pixels.shape[1], pixels.shape[0])
        image_coeffs, report, energy, projected_size, diffuse_truncation = project_pixels(pixels, order)
        del pixels
        if report.repaired:
            notes.append(f"image pixels repaired: {report.summary()}")
        truncation = resample.truncation_fraction(image_coeffs, energy)
        image_coeffs *= source.strength
    q = source.mapping.sh_rotation() if source.mapping is not None else np.eye(3)
    coeffs = rotation.rotate(image_coeffs, q)
    if not np.all(np.isfinite(coeffs)):
        raise WorldError(f"World '{source.world_name}' gave non-finite lighting")
    if not np.any(image_coeffs[0] > 0.0):
        raise WorldError(f"World '{source.world_name}' emits no light (its radiance is zero everywhere)")
    return WorldProjection(
        order=order,
        image_coeffs=image_coeffs,
        rotation=q,
        coeffs=coeffs,
        source=source,
        seconds=time.perf_counter() - start,
        truncation=truncation,
        diffuse_truncation=diffuse_truncation,
        source_size=source_size,
        projected_size=projected_size,
        warnings=notes,
    )


def store(scene, result):
    """Write a WorldProjection on the scene (ID properties + scene.prt_world), all at once."""
    settings = scene.prt_world
    source = result.source
    scene[SH_KEY] = result.image_coeffs.ravel().tolist()
    scene[SH_WORLD_KEY] = result.coeffs.ravel().tolist()
    settings.stored_order = result.order
    settings.source_kind = source.kind
    settings.world_name = source.world_name
    settings.source_node = source.node_name
    settings.image_name = source.image.name if source.image is not None else ""
    settings.image_size = result.source_size
    settings.projected_size = result.projected_size
    settings.mapping_node = source.mapping.node_name if source.mapping is not None else ""
    settings.mapping_type = source.mapping.vector_type if source.mapping is not None else ""
    settings.mapping_rotation = source.mapping.euler if source.mapping is not None else (0.0, 0.0, 0.0)
    settings.rotation_matrix = result.rotation.ravel().tolist()
    settings.seconds = result.seconds
    settings.truncation = result.truncation
    settings.diffuse_truncation = result.diffuse_truncation
    settings.message = "; ".join(result.warnings)
    settings.token = uuid.uuid4().hex


def project_and_store(scene, order=None):
    """Project and store; returns the WorldProjection. On WorldError nothing is changed."""
    if order is None:
        order = scene.prt_world.order
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or not 1 <= order <= MAX_ORDER:
        raise WorldError(f"the SH order must be an integer from 1 to {MAX_ORDER}, got {order!r}")
    result = project(scene, int(order))
    store(scene, result)
    return result


# --- live lighting ----------------------------------------------------------------------------

_cache = {}


def stored_image_coeffs(scene):
    """(n*n, 3) float64 stored unrotated coefficients, or None."""
    settings = getattr(scene, "prt_world", None)
    data = scene.get(SH_KEY) if settings is not None else None
    n = settings.stored_order if settings is not None else 0
    if data is None or n < 1 or len(data) != n * n * 3:
        return None
    return np.array(data.to_list() if hasattr(data, "to_list") else data, dtype=np.float64).reshape(n * n, 3)


def current_rotation(scene):
    """The SH rotation Q for the world's Mapping node now, or the stored one if it cannot be read."""
    settings = scene.prt_world
    stored = np.array(settings.rotation_matrix, dtype=np.float64).reshape(3, 3)
    if settings.source_kind != "IMAGE" or not settings.mapping_node:
        return stored
    world = scene.world
    if world is None or world.node_tree is None:
        return stored
    node = world.node_tree.nodes.get(settings.mapping_node)
    if node is None or node.bl_idname != "ShaderNodeMapping":
        return stored
    euler = tuple(node.inputs["Rotation"].default_value)
    return mapping_sh_rotation(node.vector_type, euler)


def current_world_coeffs(scene):
    """World-space (n*n, 3) float64 coefficients for the Mapping rotation now, or None.

    Cheap enough to call every redraw: the rotated result is cached per stored projection and
    rotation.
    """
    settings = getattr(scene, "prt_world", None)
    if settings is None or settings.stored_order < 1:
        return None
    q = current_rotation(scene)
    key = (settings.token, q.tobytes())
    cached = _cache.get(scene.as_pointer())
    if cached is not None and cached[0] == key:
        return cached[1].copy()
    coeffs = stored_image_coeffs(scene)
    if coeffs is None:
        return None
    result = rotation.rotate(coeffs, q)
    _cache[scene.as_pointer()] = (key, result)
    return result.copy()
