"""The viewport's specular sky: GGX-prefiltered levels of the world in its own frame, and the BRDF table.

The world is prefiltered once per projection (core.ibl.sky_prefilter), unrotated: the shader
turns its lookup direction by the lighting rotation's matrix (world radiance at w is the image's
at Q^T w, world.projection's Q), so turning the lighting costs nothing. With the light split,
the levels hold the residual sky (the lights are drawn analytically, shader_specular), as the
SH light does. The levels are the slices of one RGBA16F 3D texture, each with one wrapped column
on either side (core.ibl.sky_prefilter.wrapped_columns): the GPU's own trilinear filter (the
Python module's float textures filter linearly and clamp to the edge) then does the bilinear
lookup in a level, its longitude wrap and the blend between the two nearest levels in one fetch.
"""

import time

import gpu
import numpy as np

from ...core.ibl import sky_prefilter
from ...core.specular import brdf
from .. import caches
from ..world import light_split, nodes as _nodes, projection as _world
from ..world.pixels import NeedsRender, read_image_pixels, render_world

_cache = {}  # "sky": (key, SkyTexture); "brdf": texture


class SkyTexture:
    def __init__(self, texture, levels, height, width, seconds):
        self.texture = texture
        self.levels = levels
        self.height = height
        self.width = width
        self.seconds = seconds

    @property
    def nbytes(self):
        return self.levels * self.height * (self.width + 2) * 8  # RGBA16F, the wrapped columns included


@caches.on_clear
def clear_sky():
    _cache.clear()


def _sky_pixels(scene):
    """(equirect pixels or None, constant RGB or None) of the scene's world in its image frame,
    strength applied, the split lights taken out when the stored projection split them."""
    settings = scene.prt_world
    source = _nodes.analyse_world(scene)
    if source.kind == "COLOR":
        return None, np.clip(np.asarray(source.color, dtype=np.float64)[:3] * source.strength, 0.0, None)
    pixels = None
    if source.kind == "IMAGE":
        try:
            pixels = read_image_pixels(source.image)[:, :, :3]
        except NeedsRender:
            pixels = None
    strength = float(source.strength) if pixels is not None else 1.0
    if pixels is None:  # (a render shows the world as the scene sees it: Mapping and strength in)
        pixels = render_world(scene, sky_prefilter.WIDTH)
    if settings.stored_split:
        threshold = 0.0 if settings.auto_threshold else settings.light_threshold
        threshold, max_lights = light_split.check_split_settings(threshold, settings.max_lights)
        pixels, _lights = light_split.split(pixels, threshold, max_lights)
    return np.asarray(pixels, dtype=np.float64) * strength, None


def sky_texture(scene):
    """The cached SkyTexture of the scene's stored projection (None without one)."""
    settings = getattr(scene, "prt_world", None)
    if settings is None or settings.stored_order < 1:
        return None
    key = (settings.token, scene.as_pointer())
    cached = _cache.get("sky")
    if cached is not None and cached[0] == key:
        return cached[1]
    start = time.perf_counter()
    pixels, colour = _sky_pixels(scene)
    levels = sky_prefilter.constant_levels(colour) if pixels is None else sky_prefilter.sky_levels(pixels)
    sky = levels_texture(levels)
    sky.seconds = time.perf_counter() - start
    _cache["sky"] = (key, sky)
    return sky


def levels_texture(levels):
    """A SkyTexture of (levels, H, W, 3) radiance: the 3D texture of the levels, wrapped columns added."""
    count, height, width, _ = levels.shape
    data = np.ones((count, height, width + 2, 4), dtype=np.float32)
    data[..., :3] = sky_prefilter.wrapped_columns(levels)
    buf = gpu.types.Buffer("FLOAT", data.size, data.reshape(-1))
    tex = gpu.types.GPUTexture((width + 2, height, count), format="RGBA16F", data=buf)
    return SkyTexture(tex, count, height, width, 0.0)


def sky_rows(scene):
    """(3, 3) world -> image-frame rows: Q^T for the lighting rotation now."""
    return _world.current_rotation(scene).T


def brdf_texture():
    """The split-sum table (core.specular.brdf) as an RG of an RGBA32F texture (filtered linearly,
    clamped to the edge: the table's own bilinear lookup), made once."""
    tex = _cache.get("brdf")
    if tex is None:
        table = brdf.brdf_table()
        size = table.shape[0]
        data = np.zeros((size, size, 4), dtype=np.float32)
        data[:, :, :2] = table
        buf = gpu.types.Buffer("FLOAT", data.size, data.reshape(-1))
        tex = gpu.types.GPUTexture((size, size), format="RGBA32F", data=buf)
        _cache["brdf"] = tex
    return tex
