"""Albedo images as GPU textures (scene-linear RGBA16F, from image_pixels), cached per image; their GLSL.

The fragment shader reads them with albedo_at(uv) as the Image Texture node samples them:
albedo_mode (interpolation, extension) chooses Linear (texel centres at (i + 0.5) / size) or
Closest, and Repeat, Extend, Clip (texels outside are black) or Mirror, written out with
texelFetch. An image is read again when its name, size, source, file, colour space or dirty flag
changes.
"""

import gpu
import numpy as np

from .. import caches
from ..scene.albedo_source import colour_space_note, image_pixels, slot_sources

ALBEDO_SLOT = 5  # sampler slot (0 transfer, 1 and 2 shadow maps, 3 and 4 the specular's, 9 the colour table)

_FLOOR_MOD = """
ivec2 albedo_floor_mod(ivec2 i, ivec2 n)
{
  // (GLSL's % is undefined for negative i; the 0.5 keeps an inexact division off whole numbers)
  return i - n * ivec2(floor((vec2(i) + 0.5) / vec2(n)));
}
"""

_SAMPLER = """
vec3 albedo_texel(ivec2 i, ivec2 size)
{
  if (albedo_mode.y == 2 && (any(lessThan(i, ivec2(0))) || any(greaterThanEqual(i, size)))) {
    return vec3(0.0);  // Clip
  }
  ivec2 j = albedo_floor_mod(i, size);  // Repeat
  if (albedo_mode.y == 1 || albedo_mode.y == 2) {
    j = clamp(i, ivec2(0), size - 1);  // Extend
  }
  else if (albedo_mode.y == 3) {
    ivec2 m = albedo_floor_mod(i, 2 * size);  // Mirror: 0 .. n - 1, then n - 1 .. 0
    j = min(m, 2 * size - 1 - m);
  }
  return texelFetch(albedo_tx, j, 0).rgb;
}

vec3 albedo_at(vec2 uv)
{
  ivec2 size = textureSize(albedo_tx, 0);
  if (albedo_mode.x == 1) {
    return albedo_texel(ivec2(floor(uv * vec2(size))), size);  // Closest
  }
  vec2 p = uv * vec2(size) - 0.5;
  ivec2 a = ivec2(floor(p));
  vec2 f = p - vec2(a);
  vec3 low = mix(albedo_texel(a, size), albedo_texel(a + ivec2(1, 0), size), f.x);
  vec3 high = mix(albedo_texel(a + ivec2(0, 1), size), albedo_texel(a + ivec2(1), size), f.x);
  return mix(low, high, f.y);
}
"""


def sampler_glsl(name):
    """GLSL of {name}_at(uv): the sampler {name}_tx looked up as an Image Texture node samples,
    its (interpolation, extension) in the ivec2 {name}_mode (after GLSL, which holds the helper)."""
    return (
        _SAMPLER.replace("albedo_texel", f"{name}_texel")
        .replace("albedo_at", f"{name}_at")
        .replace("albedo_mode", f"{name}_mode")
        .replace("albedo_tx", f"{name}_tx")
    )


GLSL = "\nvec3 albedo_px;  // albedo_at(albedo_uv), set first in main()\n" + _FLOOR_MOD + _SAMPLER

_textures = {}  # image pointer -> (key, GPUTexture or None, note)
_white = []


@caches.on_clear
def clear_textures():
    _textures.clear()
    _white.clear()


def image_key(image):
    return (
        image.name,
        tuple(image.size),
        image.source,
        image.filepath_raw,
        image.colorspace_settings.name,
        image.is_float,
        image.is_dirty,
    )


def upload(rgb):
    height, width = rgb.shape[:2]
    data = np.ones((height, width, 4), dtype=np.float32)
    data[..., :3] = rgb
    buf = gpu.types.Buffer("FLOAT", data.size, data.reshape(-1))
    return gpu.types.GPUTexture((width, height), format="RGBA16F", data=buf)


def white():
    """A 1x1 white texture: what untextured slots of a textured mesh sample."""
    if not _white:
        _white.append(upload(np.ones((1, 1, 3), dtype=np.float32)))
    return _white[0]


def image_texture(image):
    """(GPUTexture or None, note) of `image`'s scene-linear pixels; None when it has none or is
    larger than the GPU's textures."""
    ptr = image.as_pointer()
    key = image_key(image)
    hit = _textures.get(ptr)
    if hit is not None and hit[0] == key:
        return hit[1], hit[2]
    limit = gpu.capabilities.max_texture_size_get()
    if max(image.size) > limit:
        tex, note = None, f"image '{image.name}' is larger than {limit} pixels, the GPU's limit"
    else:
        rgb, note = image_pixels(image)
        tex = None if rgb is None else upload(rgb)
    _textures[ptr] = (key, tex, note)
    return tex, note


def slot_textures(sources):
    """Per AlbedoSource, its texture: the image's for an image, the white one otherwise; None for
    an image that cannot be read (the caller falls back to the viewport colour)."""
    return [image_texture(src.image)[0] if src.kind == "IMAGE" else white() for src in sources]


def notes(obj):
    """What the display says about `obj`'s albedo: each slot's fallback, and what reading its
    images said (once an image was read; before, its colour space only)."""
    out = []
    for src in slot_sources(obj):
        note = src.note
        if src.kind == "IMAGE":
            hit = _textures.get(src.image.as_pointer())
            note = hit[2] if hit is not None and hit[0] == image_key(src.image) else colour_space_note(src.image)
        if note and note not in out:
            out.append(note)
    return out
