"""Texel bakes in a .glb: the transfer as 8-bit PNG planes (16 bits a value over two), the lightmap UV map a TEXCOORD.

Per baked glTF mesh of a texel bake: the coefficients rotated into glTF's frame, quantised per
coefficient (core.transfer.texel_encoding), each plane laid out in the bake's tiles
(scene.texel_storage) with every tile's rows flipped so the PNG's top row is glTF's v = 0 (the
exporter writes TEXCOORD_i = (u, 1 - v) of the mesh's i-th UV map), written as a PNG image with
a texture (nearest, clamp) in the BIN chunk; a bake with bounces adds per bounce channel its
bounced transfer's planes, encoded alike. The mesh's extras get `texel`. docs/export.md,
"Texel transfer", is the format.
"""

import numpy as np

from ...core.ibl import rgbd_png
from ...core.transfer import texel_encoding
from ..scene import texel_storage

VERSION = 3  # mesh extras of a texel transfer: readers of versions 1 and 2 know only attributes
NEAREST, CLAMP = 9728, 33071


def encoding_for(transfer):
    """The texel encoding of the export's `transfer` setting: 8-bit for snorm8, else 16-bit."""
    return "unorm8_png" if transfer == "snorm8" else "unorm16_png"


def texcoord_index(mesh, bake):
    """The TEXCOORD_i Blender's exporter writes the bake's UV map as (i: its index in uv_layers)."""
    index = mesh.uv_layers.find(bake.uv_map)
    if index < 0:
        raise ValueError(f"mesh '{mesh.name}' has no UV map '{bake.uv_map}' (the bake's)")
    return index


def _encode(values, n2, to_gltf_frame, encoding):
    """([PNG bytes per plane], [{"offset": [4], "scale": [4]} per tile]) of one part's (res, res,
    4 G) coefficients (the direct transfer or one bounce channel's), rotated into glTF's frame."""
    values = values.astype(np.float64)
    res = values.shape[0]
    rotated = to_gltf_frame(values[..., :n2].reshape(-1, n2).T).T
    values[..., :n2] = rotated.reshape(res, res, n2)
    stored, offset, scale = texel_encoding.encode(values, texel_encoding.PLANES[encoding])
    pngs = []
    for plane in stored:
        # Each tile flipped (row 0 the top: v_glTF = 0), tile g at column g % tiles_x from the left
        # and row g // tiles_x from the top.
        atlas = texel_storage.to_tiles(plane[::-1].astype(np.float32))
        pngs.append(rgbd_png.png_bytes(atlas.astype(np.uint8)))
    groups = values.shape[2] // 4
    table = [
        {"offset": offset[4 * g : 4 * g + 4].tolist(), "scale": scale[4 * g : 4 * g + 4].tolist()}
        for g in range(groups)
    ]
    return pngs, table


def planes(bake, to_gltf_frame, encoding):
    """([PNG bytes per plane], [{"offset": [4], "scale": [4]} per tile], (tiles_x, tiles_y)) of the
    direct transfer."""
    values = texel_storage.read_texel_transfer(bake, padded=True)
    pngs, table = _encode(values, bake.order * bake.order, to_gltf_frame, encoding)
    return pngs, table, texel_storage.tile_grid(bake.count)


def bounce_planes(bake, to_gltf_frame, encoding):
    """Per bounce channel (none without bounces) ([PNG bytes per plane], [decode per tile]): the
    bounced transfer's tiles, encoded and laid out as the direct ones, quantised on their own."""
    bounced = texel_storage.read_texel_bounce(bake, padded=True)
    if bounced is None:
        return []
    n2 = bake.order * bake.order
    return [_encode(bounced[:, :, c], n2, to_gltf_frame, encoding) for c in range(bounced.shape[2])]


def write(document, chunks, mesh_meta, pngs, name):
    """Append the PNGs (images, textures, a nearest clamp sampler) to the BIN chunk (chunks[0],
    replaced) and return their texture indices."""
    payload = bytearray(chunks[0][1])
    views = document.setdefault("bufferViews", [])
    images = document.setdefault("images", [])
    textures = document.setdefault("textures", [])
    samplers = document.setdefault("samplers", [])
    sampler = next(
        (i for i, s in enumerate(samplers) if s.get("name") == "PRT_transfer"),
        None,
    )
    if sampler is None:
        sampler = len(samplers)
        samplers.append(
            {"name": "PRT_transfer", "magFilter": NEAREST, "minFilter": NEAREST, "wrapS": CLAMP, "wrapT": CLAMP}
        )
    out = []
    for p, png in enumerate(pngs):
        payload += b"\0" * (-len(payload) % 8)
        views.append({"buffer": 0, "byteOffset": len(payload), "byteLength": len(png)})
        payload += png
        images.append({"name": f"PRT_transfer {name} plane{p}", "mimeType": "image/png", "bufferView": len(views) - 1})
        out.append(len(textures))
        textures.append({"name": f"PRT_transfer {name} plane{p}", "source": len(images) - 1, "sampler": sampler})
    chunks[0] = (chunks[0][0], bytes(payload))
    document["buffers"][0]["byteLength"] = len(payload)
    return out


def annotate(document, chunks, baked, to_gltf_frame, encoding, extras_key):
    """The texel bakes of `baked` ({glTF mesh index: (Blender mesh, BakeRecord)}) written into the
    document and chunks (changed in place)."""
    for index, (mesh, bake) in sorted(baked.items()):
        meta = document["meshes"][index]["extras"][extras_key]
        name = document["meshes"][index].get("name", str(index))
        pngs, table, grid = planes(bake, to_gltf_frame, encoding)
        textures = write(document, chunks, meta, pngs, name)
        texel = {
            "texcoord": texcoord_index(mesh, bake),
            "uv_map": bake.uv_map,
            "resolution": bake.resolution,
            "tiles": list(grid),
            "textures": textures,
            "decode": table,
        }
        bounced = bounce_planes(bake, to_gltf_frame, encoding)
        if bounced:
            texel["bounce_textures"] = [
                write(document, chunks, meta, part, f"{name} bounce{c}") for c, (part, _t) in enumerate(bounced)
            ]
            texel["bounce_decode"] = [part_table for _p, part_table in bounced]
        meta.update(version=VERSION, transfer_encoding=encoding, texel=texel)
