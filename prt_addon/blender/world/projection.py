"""The world projected into RGB SH lighting, stored on the scene and rotated live; docs/world.md.

Recognised node trees are read directly (world.nodes):

    [Texture Coordinate.Generated -> Mapping ->] Environment Texture.Color -> Background.Color
    constant colour -> Background.Color

with the Background strength a constant. The Mapping node's rotation is not applied to the pixels:
the image is projected in its own frame and the coefficients are rotated (stored unrotated, so a
rotation change needs no new projection, see current_world_coeffs). Any other world (Sky Texture,
gradients, mixes, 8-bit images in unusual colour spaces, a Mapping location or a non-uniform
scale) is rendered by Cycles to an equirectangular image (world.pixels), and that is projected.
"""

import time
import uuid
from dataclasses import dataclass, field

import numpy as np

from ...core.lights import extraction as core_lights
from ...core.sh import basis as sh, projection, resample, rotation
from .. import caches
from . import light_split
from .nodes import WorldError, WorldSource, _render_source, analyse_world, live_sh_rotation
from .pixels import NeedsRender, read_image_pixels, render_world

SH_KEY = "prt_world_sh"  # unrotated (image-frame) coefficients, flat, index 3 * i + channel


SH_WORLD_KEY = "prt_world_sh_world"  # world-space coefficients as projected (rotation applied)


MAX_ORDER = 32  # the Order property's maximum; (order**2, 3) coefficients


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
    warnings: list = field(default_factory=list)  # what the user should know or do (the panel shows them)
    info: list = field(default_factory=list)  # what was done that needs no action (the operator's report only)
    split: bool = False  # whether the light split ran (an IMAGE or RENDER source with it on)
    lights: list = field(default_factory=list)  # core.lights.extraction.Light, image frame, strength applied
    light_share: float = 0.0  # fraction of the world's luminance power in the lights


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


def project(scene, order, force_render=False, split_lights=None, threshold=None, max_lights=None):
    """Project scene.world: a WorldProjection (nothing is stored). Raises WorldError.

    split_lights, threshold (0: automatic), max_lights: None uses the scene's setting. With the
    split, the lights are taken from the full-resolution pixels and the residual is projected.
    """
    try:
        order = sh.check_order(order)
    except ValueError as error:
        raise WorldError(str(error)) from None
    settings = getattr(scene, "prt_world", None)
    split_lights = bool(getattr(settings, "split_lights", False) if split_lights is None else split_lights)
    if threshold is None:  # (0 is the automatic threshold)
        threshold = 0.0 if getattr(settings, "auto_threshold", True) else getattr(settings, "light_threshold", 0.0)
    max_lights = getattr(settings, "max_lights", core_lights.MAX_LIGHTS // 2) if max_lights is None else max_lights
    threshold, max_lights = light_split.check_split_settings(threshold, max_lights)
    start = time.perf_counter()
    source = analyse_world(scene)
    notes, info = [], []
    if force_render and source.kind != "RENDER":
        source = _render_source(scene.world, None, "a render was requested")
    pixels = None
    if source.kind == "IMAGE":
        try:
            pixels = read_image_pixels(source.image)
        except NeedsRender as why:
            source = _render_source(scene.world, None, str(why))
    truncation = diffuse_truncation = 0.0
    source_size = projected_size = (0, 0)
    lights = []
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
        if split_lights:
            pixels, lights = light_split.split(pixels, threshold, max_lights)
        image_coeffs, report, energy, projected_size, diffuse_truncation = project_pixels(pixels, order)
        del pixels
        if report.repaired:
            # Small negative values are common in HDRIs (compression, denoising): nothing to do.
            (notes if report.nan or report.inf else info).append(report.in_words())
        truncation = resample.truncation_fraction(image_coeffs, energy)
        image_coeffs *= source.strength
        lights = light_split.scaled(lights, source.strength)
    q = source.mapping.sh_rotation() if source.mapping is not None else np.eye(3)
    coeffs = rotation.rotate(image_coeffs, q)
    if not np.all(np.isfinite(coeffs)):
        raise WorldError(f"World '{source.world_name}' gave non-finite lighting")
    if not np.any(image_coeffs[0] > 0.0) and not lights:
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
        info=info,
        split=split_lights and source.kind != "COLOR",
        lights=lights,
        light_share=light_split.share(lights, image_coeffs),
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
    light_split.store(scene, result.lights)
    settings.stored_split = result.split
    settings.light_count = len(result.lights)
    settings.light_share = result.light_share
    settings.strongest_elevation = light_split.elevation(result.lights[0], result.rotation) if result.lights else 0.0
    settings.token = uuid.uuid4().hex


def project_and_store(scene, order=None, split_lights=None, threshold=None, max_lights=None):
    """Project and store; returns the WorldProjection. On WorldError nothing is changed.
    split_lights, threshold, max_lights: None uses the scene's setting (see project)."""
    if order is None:
        order = scene.prt_world.order
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or not 1 <= order <= MAX_ORDER:
        raise WorldError(f"the SH order must be an integer from 1 to {MAX_ORDER}, got {order!r}")
    result = project(scene, int(order), split_lights=split_lights, threshold=threshold, max_lights=max_lights)
    store(scene, result)
    return result


_cache = {}  # scene pointer -> (key, the lights in world space)


@caches.on_clear
def clear_cache():
    _cache.clear()


def stored_image_coeffs(scene):
    """(n*n, 3) float64 stored unrotated coefficients, or None."""
    settings = getattr(scene, "prt_world", None)
    data = scene.get(SH_KEY) if settings is not None else None
    n = settings.stored_order if settings is not None else 0
    if data is None or n < 1 or len(data) != n * n * 3:
        return None
    return np.array(data.to_list() if hasattr(data, "to_list") else data, dtype=np.float64).reshape(n * n, 3)


def current_rotation(scene):
    """The SH rotation Q for the world's node tree now (world.nodes.live_sh_rotation: a Mapping
    node added, removed, muted, relinked or behind a reroute gives what Cycles shows), or the
    stored one when the world is not an image with a representable Mapping node any more."""
    settings = scene.prt_world
    stored = np.array(settings.rotation_matrix, dtype=np.float64).reshape(3, 3)
    if settings.source_kind != "IMAGE":
        return stored
    live = live_sh_rotation(scene.world)
    return stored if live is None else live


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


def current_world_lights(scene):
    """The stored split lights in world space for the Mapping rotation now (core.lights.extraction.Light
    list: a light at image direction s is at Q s, the Q of the SH), [] when there are none."""
    settings = getattr(scene, "prt_world", None)
    if settings is None or settings.stored_order < 1:
        return []
    lights = light_split.stored(scene)
    return core_lights.rotate_lights(lights, current_rotation(scene)) if lights else []
