"""The float images of texel bakes: their tile layout, writing them packed in the .blend, reading them.

A texel bake of order n has n^2 coefficients per texel, four to an RGBA texel: G = ceil(n^2 / 4)
tiles of res x res, laid out in a grid of `tiles_x` columns (tile g at column g % tiles_x, row
g // tiles_x) so the image stays within the GPU's texture size. An interreflected bake with C
bounce channels (1 or 3) has (1 + C) G tiles: the direct transfer's G, then each channel's
bounced transfer as G more (tile c G + g). The back side of an open mesh is an image of its own,
G tiles of its direct transfer (image_name(mesh, back=True)). Row 0 of every tile is v = 0, as
in Image.pixels. The images are Non-Color float images (is_data: the values are kept exactly,
negative ones too), packed (saved in the .blend as OpenEXR) with a fake user.
"""

import math

import bpy
import numpy as np

from .mesh_read import uv_fingerprint, uv_map_names

IMAGE_PREFIX = "PRT "
RECORD = "prt_bake"


BACK_SUFFIX = " (back)"


def image_name(mesh, back=False):
    """The name users see for a mesh's transfer image: "PRT <mesh name>", and for the back side
    of an open mesh "PRT <mesh name> (back)"."""
    return f"{IMAGE_PREFIX}{mesh.name}{BACK_SUFFIX if back else ''}"


def tile_grid(groups):
    """(tiles_x, tiles_y) of `groups` tiles: about square."""
    tiles_x = max(1, math.ceil(math.sqrt(groups)))
    return tiles_x, max(1, math.ceil(groups / tiles_x))


def to_tiles(image):
    """(res, res, 4 G) coefficients (padded with zeros to a multiple of 4) -> (H, W, 4) pixels."""
    res = image.shape[0]
    channels = image.shape[2]
    groups = -(-channels // 4)
    tiles_x, tiles_y = tile_grid(groups)
    out = np.zeros((tiles_y * res, tiles_x * res, 4), dtype=np.float32)
    for g in range(groups):  # (no padded copy of the image: 1 GiB at 2048 x 2048, order 8)
        row, col = divmod(g, tiles_x)
        k = min(4, channels - 4 * g)
        out[row * res : (row + 1) * res, col * res : (col + 1) * res, :k] = image[..., 4 * g : 4 * g + k]
    return out


def from_tiles(pixels, res, groups):
    """(H, W, 4) pixels -> (res, res, 4 G) coefficients (the inverse of to_tiles)."""
    tiles_x, _ = tile_grid(groups)
    out = np.empty((res, res, 4 * groups), dtype=np.float32)
    for g in range(groups):
        row, col = divmod(g, tiles_x)
        out[..., 4 * g : 4 * g + 4] = pixels[row * res : (row + 1) * res, col * res : (col + 1) * res]
    return out


def pack_parts(image, bounce, groups):
    """(res, res, 4 G (1 + C)) coefficients of the direct (res, res, n*n) image and the bounced
    (res, res, C, n*n) one (or None), each part padded to 4 G channels (the module docstring)."""
    if bounce is None:
        return np.asarray(image, np.float32)
    res, channels = image.shape[0], bounce.shape[2]
    out = np.zeros((res, res, 4 * groups * (1 + channels)), dtype=np.float32)
    n2 = image.shape[2]
    out[..., :n2] = image
    for c in range(channels):
        first = 4 * groups * (1 + c)
        out[..., first : first + n2] = bounce[:, :, c]
    return out


def write_uv_map(mesh, uv_name, created_uvs):
    """Add the UV map a bake made (`created_uvs`, (corners, 2)) as `uv_name`; returns its name."""
    if created_uvs is None:
        return uv_name
    layer = mesh.uv_layers.get(uv_name) or mesh.uv_layers.new(name=uv_name, do_init=False)
    if layer is None:
        raise ValueError(f"cannot add the UV map '{uv_name}' to '{mesh.name}' (a mesh holds at most 8)")
    mesh.attributes[layer.name].data.foreach_set("vector", np.ascontiguousarray(created_uvs, np.float32).reshape(-1))
    return layer.name


def record_fields(mesh, res, uv_name, channels=0, back=False):
    """The bake record's texel fields: resolution, UV map and its fingerprint, the image's name,
    the bounce channels and the format version (3, or 4 with bounce tiles: older readers refuse
    what they would misread, and read the rest); with `back`, the back side's image (`back`,
    `back_image`: older readers draw the front, as before)."""
    fields = {
        "bounce_channels": int(channels),
        "version": 4 if channels else 3,
        "resolution": res,
        "uv_map": uv_name,
        "uv_fingerprint": uv_fingerprint(mesh, uv_name),
        "image": image_name(mesh),
    }
    if back:
        fields.update(back=1, back_image=image_name(mesh, back=True))
    return fields


def write_texels(mesh, image, record, count, uv, staged, bounce=None, back=None):
    """Write a texel bake's (res, res, n*n) coefficients as a staged image (`staged` gets
    (mesh, record key, image); storage.write_bakes commits them), the UV map it made (uv: (name,
    (corners, 2) UVs or None)) and the record with `count` tiles per part; bounce: None or the
    (res, res, C, n*n) bounced transfer, its channels as further tiles; back: None or the back
    side's (res, res, n*n), an image of its own."""
    uv_name = write_uv_map(mesh, *uv)
    packed = pack_parts(image, bounce, count)
    for key, values in (("image", packed), ("back_image", back)):
        if values is not None:
            name = image_name(mesh, back=key == "back_image")
            staged.append((mesh, key, stage_image(name, np.asarray(values, np.float32))))
    channels = 0 if bounce is None else bounce.shape[2]
    fields = record_fields(mesh, image.shape[0], uv_name, channels, back is not None)
    mesh[RECORD] = dict(record, count=count, domain="TEXEL", **fields)
    mesh.update()


def record_images(record):
    """The names of a texel bake's images in a record (a dict, or None): the front's, the back's."""
    if not isinstance(record, dict) or record.get("domain") != "TEXEL":
        return set()
    return {str(record[key]) for key in ("image", "back_image") if record.get(key)}


def stage_image(name, image):
    """A new packed float image holding (res, res, C) coefficients, under a temporary name (the
    caller renames it to `name` once every mesh of the bake is written)."""
    tiles = to_tiles(image)
    height, width = tiles.shape[:2]
    staged = bpy.data.images.new(f"{name} (baking)", width, height, alpha=True, float_buffer=True, is_data=True)
    try:
        staged.pixels.foreach_set(tiles.reshape(-1))
        del tiles  # (before pack() makes its own copy)
        staged.pack()
        staged.use_fake_user = True
    except BaseException:
        bpy.data.images.remove(staged)
        raise
    return staged


def commit_image(staged, name):
    """Give the staged image its final name, replacing the previous image of that name."""
    old = bpy.data.images.get(name)
    if old is not None and old != staged:
        bpy.data.images.remove(old)
    staged.name = name
    return staged.name


def discard_image(staged):
    if staged is not None and staged.name in bpy.data.images:
        bpy.data.images.remove(staged)


def remove_image(name):
    image = bpy.data.images.get(name) if name else None
    if image is not None:
        bpy.data.images.remove(image)


def find_image(name, res, groups):
    """The transfer image `name` when it exists with the size of `groups` tiles of res, else None."""
    image = bpy.data.images.get(name) if name else None
    if image is None:
        return None
    tiles_x, tiles_y = tile_grid(groups)
    if tuple(image.size) != (tiles_x * res, tiles_y * res):
        return None
    return image


def find_back_image(record, res, groups):
    """(the back side's transfer image or None, why it is unreadable or "") of a texel record."""
    if not int(record.get("back", 0)):
        return None, ""
    name = str(record.get("back_image", ""))
    image = find_image(name, res, groups)
    return (None, f"its back-side image '{name}' is missing or was resized") if image is None else (image, "")


def read_pixels(image):
    """(H, W, 4) float32 pixels of an image."""
    width, height = image.size
    buf = np.empty(width * height * 4, dtype=np.float32)
    image.pixels.foreach_get(buf)
    return buf.reshape(height, width, 4)


def read_coefficients(image, res, groups):
    """(res, res, 4 G) float32 coefficients of a transfer image."""
    return from_tiles(read_pixels(image), res, groups)


def total_groups(bake):
    """The tiles of a texel bake's image: count of the direct transfer and of each bounce channel."""
    return bake.count * (1 + bake.channels)


def _read_part(bake, part, padded):
    tiles_x, _ = tile_grid(total_groups(bake))
    pixels = read_pixels(bake.image)
    res, out = bake.resolution, []
    for g in range(part * bake.count, (part + 1) * bake.count):
        row, col = divmod(g, tiles_x)
        out.append(pixels[row * res : (row + 1) * res, col * res : (col + 1) * res])
    values = np.concatenate(out, axis=2)
    return np.ascontiguousarray(values if padded else values[..., : bake.order * bake.order])


def read_texel_transfer(bake, padded=False):
    """(res, res, n*n) float32 coefficients of a texel bake (4 * count with padded)."""
    return _read_part(bake, 0, padded)


def read_texel_bounce(bake, padded=False):
    """(res, res, C, n*n) float32 bounced transfer of a texel bake (C = 1 or 3), or None
    without bounces."""
    if not bake.channels:
        return None
    return np.stack([_read_part(bake, 1 + c, padded) for c in range(bake.channels)], axis=2)


def read_texel_back(bake, padded=False):
    """(res, res, n*n) float32 back-side coefficients of a texel bake (4 * count with padded)."""
    values = from_tiles(read_pixels(bake.back_image), bake.resolution, bake.count)
    return np.ascontiguousarray(values if padded else values[..., : bake.order * bake.order])


def stale_uv_map(mesh, bake):
    """Why a texel bake's UV map no longer matches (removed, or its UVs changed), or ""."""
    if bake.uv_map not in uv_map_names(mesh):
        return f"its UV map '{bake.uv_map}' was removed or renamed"
    stored = bake.record.get("uv_fingerprint")
    if stored is not None and uv_fingerprint(mesh, bake.uv_map) != str(stored):
        return f"its UV map '{bake.uv_map}' changed since the bake"
    return ""
