"""A material's Specular IOR Level and IOR images folded into one per-pixel dielectric F0 image for the web plugin.

glTF has no IOR texture (KHR_materials_ior is a constant), and Blender's exporter writes a Specular
IOR Level image as KHR_materials_specular's specularTexture as it is (its RGB; glTF reads that
texture's alpha), so the plugin reads neither: the export carries F0 = ((IOR - 1) / (IOR + 1))^2 x
2 x level (core.specular.brdf.dielectric_f0), each of IOR and level the pixel's image value or the
constant, as float16 texels in the BIN chunk, referenced from the material's PRT_lighting extras
(`f0_map`, docs/export.md). When both are images of different sizes, the smaller is looked up at
the larger's texel centres as its node samples it (core.transfer.image_sampling), and the F0 image
is sampled as the larger's node says.
"""

import numpy as np

from ...core.specular import brdf
from ...core.transfer import image_sampling
from ..scene.albedo_source import mesh_source
from ..scene.principled_maps import RANGES, map_pixels, mesh_maps

LEVEL, IOR = 2, 3  # (their places in principled_maps.INPUTS)
INTERPOLATION = {image_sampling.LINEAR: "LINEAR", image_sampling.CLOSEST: "CLOSEST"}
EXTENSION = {
    image_sampling.REPEAT: "REPEAT",
    image_sampling.EXTEND: "EXTEND",
    image_sampling.CLIP: "CLIP",
    image_sampling.MIRROR: "MIRROR",
}


def _values(item, index):
    """(h, w) values of a MapInput in its input's range (row 0 the bottom), or None."""
    if item is None:
        return None
    lower, upper = RANGES[index]
    values, _note = map_pixels(item.image, item.channel, item.factor, upper, lower)
    return values


def _at_texel_centres(values, sampling, shape):
    """(h, w) lookup of `values` at the texel centres of a (h, w) grid, as its node samples it."""
    h, w = shape
    u, v = np.meshgrid((np.arange(w) + 0.5) / w, (np.arange(h) + 0.5) / h)
    uv = np.stack([u.ravel(), v.ravel()], axis=1)
    return image_sampling.sample_image(values[..., None], uv, np.float64, *sampling).reshape(h, w)


def f0_pixels(maps):
    """((h, w) float32 dielectric F0, row 0 the bottom, (interpolation, extension)) of a SlotMaps
    whose Specular IOR Level or IOR comes from a readable image, else None."""
    items = {index: maps.inputs[index] for index in (LEVEL, IOR)}
    values = {index: _values(item, index) for index, item in items.items()}
    read = [index for index in (LEVEL, IOR) if values[index] is not None]
    if not read:
        return None
    grid = max(read, key=lambda index: values[index].size)
    shape = values[grid].shape
    for index in read:
        if values[index].shape != shape or items[index].sampling != items[grid].sampling:
            values[index] = _at_texel_centres(values[index], items[index].sampling, shape)
    level = maps.level if values[LEVEL] is None else values[LEVEL]
    if values[IOR] is None:
        f0 = np.clip(maps.f0_per_level * np.asarray(level, np.float64), 0.0, 1.0)  # (the constant IOR's)
    else:
        f0 = brdf.dielectric_f0(values[IOR], level)
    return np.broadcast_to(f0, shape).astype(np.float32), items[grid].sampling


def f0_block(material, mesh, append):
    """The `f0_map` extras of `material` on `mesh` (its maps' UV map as the TEXCOORD index Blender's
    exporter writes: the map's index in uv_layers), the texels (float16, row 0 glTF's v = 0, the
    image's top) appended by `append(bytes) -> bufferView index`; None without a level or IOR image
    the viewport draws (the same fallbacks: scene.principled_maps.mesh_maps, beside the base colour's UV map)."""
    if material is None or mesh is None:
        return None
    albedo = mesh_source(material, mesh)
    maps = mesh_maps(material, mesh, albedo.uv_map if albedo.kind == "IMAGE" else None)
    found = f0_pixels(maps) if maps.any else None
    if found is None:
        return None
    f0, (interpolation, extension) = found
    height, width = f0.shape
    return {
        "bufferView": append(f0[::-1].astype("<f2").tobytes()),
        "width": width,
        "height": height,
        "format": "float16_r",
        "texCoord": max(mesh.uv_layers.find(maps.uv_map), 0),
        "interpolation": INTERPOLATION[interpolation],
        "extension": EXTENSION[extension],
    }
