"""The Principled specular in the .glb: the residual sky's GGX levels, the split-sum table, each material's constants.

What the web plugin needs to draw the viewport's specular (docs/specular.md): the sky prefiltered
as the viewport prefilters it (core.ibl.sky_prefilter, in the image's own frame, the split lights
taken out when the projection split them: the plugin draws those analytically), the frame that
takes a glTF world direction into that image frame, the split-sum table of core.specular.brdf,
and per Principled material its roughness, metallic, dielectric F0 and GGX lobe bands
(core.specular.occlusion.lobe_bands, and the open transfer's part of them). Float data go into
the BIN chunk as bufferViews (sky: float16 RGB, table: float32 RG), referenced from the scene's
PRT_lighting extras.
"""

import numpy as np

from ...core.ibl import sky_prefilter
from ...core.sh import analytic
from ...core.specular import brdf, occlusion
from ..scene.principled import principled_specular
from ..scene.principled_maps import map_pixels, principled_maps
from ..world import light_split, nodes as _nodes, projection as _world
from ..world.pixels import NeedsRender, read_image_pixels, render_world
from .dielectric_map import f0_block

BAND_COUNT = 32  # lobe bands per material: enough for any order the display draws
# Blender (Z up) to glTF (Y up), as gltf.BLENDER_TO_GLTF.
_BLENDER_TO_GLTF = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def residual_sky(scene):
    """(equirect pixels or None, constant RGB or None) of the world in its image frame, strength
    applied, the split lights taken out when the stored projection split them (as the viewport's
    sky). Raises WorldError."""
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


def sky_levels(scene):
    """(levels, H, W, 3) of the residual sky, and (3, 3) rows taking a glTF world direction into
    the image frame (Q^T of the lighting rotation now, after glTF -> Blender)."""
    pixels, colour = residual_sky(scene)
    levels = sky_prefilter.constant_levels(colour) if pixels is None else sky_prefilter.sky_levels(pixels)
    rows = _world.current_rotation(scene).T @ _BLENDER_TO_GLTF.T
    return levels, rows


def _lobe(roughness):
    """(bands, open part) of the GGX lobe at `roughness` for the specular occlusion."""
    bands = occlusion.lobe_bands(float(max(roughness * roughness, 1e-3)), BAND_COUNT)
    # The open transfer's lobe-weighted part per band, by the addition theorem: k_l z_l sqrt((2l + 1) / 4 pi).
    ls = np.arange(BAND_COUNT)
    open_ = bands * analytic.clamped_cosine_zonal(BAND_COUNT) * np.sqrt((2 * ls + 1) / (4 * np.pi))
    return np.asarray(bands).tolist(), open_.tolist()


def _mapped(material):
    """(names of the inputs the viewport reads from an image, (smallest, largest) roughness of
    its image or None)."""
    found = principled_maps(material)
    names, span = [], None
    for name, item in zip(("roughness", "metallic", "specular_ior_level", "ior"), found.inputs):
        if item is None or item.image.size[0] == 0 or item.image.size[1] == 0:
            continue
        names.append(name)
        if name == "roughness":
            values, _note = map_pixels(item.image, item.channel, item.factor)
            span = (float(values.min()), float(values.max()))
    return names, span


def material_extras(material, mesh=None, append=None):
    """The PRT_lighting extras of a Principled material, or None for any other. A material whose
    Roughness, Metallic, Specular IOR Level or IOR comes from an image (scene.principled_maps) also
    lists them in `maps` (the plugin reads roughness and metallic from the file's
    metallicRoughnessTexture, and the other two folded into `f0_map`, dielectric_map.f0_block,
    on `mesh` with `append`), and its roughness image's range with the lobe at its largest value
    (`lobe_bands2`, `lobe_open2`; the first lobe is at its smallest), as the viewport's occlusion
    mixes them."""
    params = principled_specular(material)
    if params is None:
        return None
    roughness, metallic, f0 = params
    names, span = _mapped(material)
    if span is not None:
        roughness = span[0]
    bands, open_ = _lobe(roughness)
    extras = {"roughness": roughness, "metallic": metallic, "f0": f0, "lobe_bands": bands, "lobe_open": open_}
    if names:
        span = span or (roughness, roughness)
        extras["maps"] = names
        extras["roughness_range"] = list(span)
        extras["lobe_bands2"], extras["lobe_open2"] = _lobe(span[1])
        f0_map = f0_block(material, mesh, append) if append is not None else None
        if f0_map is not None:
            extras["f0_map"] = f0_map
    return extras


def _append(document, chunks, chunk_bin, data):
    """Append bytes to the BIN chunk as a new bufferView; -> its index."""
    index = next((k for k, (kind, _p) in enumerate(chunks) if kind == chunk_bin), None)
    if index is None:
        chunks.insert(0, (chunk_bin, b""))
        document.setdefault("buffers", []).insert(0, {"byteLength": 0})
        for view in document.get("bufferViews", []):
            view["buffer"] += 1
        index = 0
    payload = bytearray(chunks[index][1])
    payload += b"\0" * (-len(payload) % 4)
    views = document.setdefault("bufferViews", [])
    views.append({"buffer": 0, "byteOffset": len(payload), "byteLength": len(data)})
    payload += data
    chunks[index] = (chunk_bin, bytes(payload))
    document["buffers"][0]["byteLength"] = len(payload)
    return len(views) - 1


def enabled(scene):
    """Whether the scene draws the specular (its display's Specular): the file carries it then."""
    return bool(getattr(getattr(scene, "prt_display", None), "specular", False))


def prepare(scene):
    """(sky levels, rows, split-sum table) of the scene, made before anything is written. Raises
    WorldError."""
    levels, rows = sky_levels(scene)
    return np.clip(levels, 0.0, 65504.0), rows, brdf.brdf_table()


def write(document, chunks, chunk_bin, prepared, materials, key):
    """Add the specular data (prepare's): the sky levels and the table to the BIN chunk (changed
    in place) and the scene extras[key]["specular"]; each glTF material named after a Principled
    material of `materials` ({name: (Blender material, a mesh using it)}) gets extras[key]."""
    levels, rows, table = prepared
    count, height, width, _ = levels.shape
    sky_view = _append(document, chunks, chunk_bin, levels.astype("<f2").tobytes())
    table_view = _append(document, chunks, chunk_bin, table.astype("<f4").tobytes())
    block = {
        "sky": {"bufferView": sky_view, "levels": count, "width": width, "height": height, "format": "float16_rgb"},
        "sky_rows": rows.tolist(),
        "brdf": {"bufferView": table_view, "size": table.shape[0], "format": "float32_rg"},
    }
    for gltf_scene in document.get("scenes", []):
        gltf_scene.setdefault("extras", {}).setdefault(key, {})["specular"] = block
    for gltf_material in document.get("materials", []):
        material, mesh = materials.get(gltf_material.get("name"), (None, None))
        extras = material_extras(material, mesh, lambda data: _append(document, chunks, chunk_bin, data))
        if extras is not None:
            own = gltf_material.get("extras")
            gltf_material["extras"] = own if isinstance(own, dict) else {}
            gltf_material["extras"][key] = extras
