"""What a material's diffuse albedo comes from: a constant colour, an image on a UV map, or a colour attribute."""

from dataclasses import dataclass, replace

import numpy as np

from ...core.transfer import image_sampling
from .materials import active_output, colour_attribute

DIFFUSE_INPUTS = {"ShaderNodeBsdfPrincipled": "Base Color", "ShaderNodeBsdfDiffuse": "Color"}
# An Image Texture node's sampling as the display's albedo_mode: (interpolation, extension).
# Cubic and Smart are drawn as Linear.
INTERPOLATION_MODES = {
    "Linear": image_sampling.LINEAR,
    "Closest": image_sampling.CLOSEST,
    "Cubic": image_sampling.LINEAR,
    "Smart": image_sampling.LINEAR,
}
EXTENSION_MODES = {
    "REPEAT": image_sampling.REPEAT,
    "EXTEND": image_sampling.EXTEND,
    "CLIP": image_sampling.CLIP,
    "MIRROR": image_sampling.MIRROR,
}


@dataclass(frozen=True)
class AlbedoSource:
    """kind 'CONSTANT' (colour), 'IMAGE' (image on uv_map, "" = the active one, times colour) or
    'ATTRIBUTE' (the colour attribute `attribute`, "" = the active one, times colour); note: why a
    fallback was taken, "" when the material was read as it is; sampling: the image node's
    (interpolation, extension) as INTERPOLATION_MODES and EXTENSION_MODES number them."""

    kind: str
    colour: tuple = (1.0, 1.0, 1.0)
    image: object = None
    uv_map: str = ""
    attribute: str = ""
    note: str = ""
    sampling: tuple = (0, 0)


def _constant(socket):
    return tuple(float(x) for x in socket.default_value)[:3]


def _multiply(node):
    """(colour input, constant factor) of a Multiply node with one constant colour, else None."""
    if node.bl_idname == "ShaderNodeMixRGB":
        fac, a, b = node.inputs["Fac"], node.inputs["Color1"], node.inputs["Color2"]
    elif node.bl_idname == "ShaderNodeMix" and node.data_type == "RGBA":
        fac, a, b = node.inputs[0], node.inputs[6], node.inputs[7]
    else:
        return None
    if node.blend_type != "MULTIPLY" or fac.is_linked or a.is_linked == b.is_linked:
        return None
    linked, const = (a, b) if a.is_linked else (b, a)
    f = float(fac.default_value if not hasattr(fac.default_value, "__len__") else fac.default_value[0])
    # mix(c, c * k, f) = c * ((1 - f) + f k)
    return linked, tuple((1.0 - f) + f * k for k in _constant(const))


def _from_socket(socket, colour, name):
    node = socket.links[0].from_node
    if node.bl_idname == "ShaderNodeTexImage":
        if node.image is None:
            return None, f"'{name}': its Image Texture node has no image"
        vector = node.inputs["Vector"]
        sampling = (INTERPOLATION_MODES.get(node.interpolation, 0), EXTENSION_MODES.get(node.extension, 0))
        if not vector.is_linked:
            return AlbedoSource("IMAGE", colour, node.image, sampling=sampling), ""
        uv = vector.links[0].from_node
        if uv.bl_idname == "ShaderNodeUVMap":
            return AlbedoSource("IMAGE", colour, node.image, uv_map=uv.uv_map, sampling=sampling), ""
        return None, f"'{name}': the image's coordinates come from a {uv.bl_idname} node"
    if node.bl_idname == "ShaderNodeVertexColor":
        return AlbedoSource("ATTRIBUTE", colour, attribute=node.layer_name), ""
    mult = _multiply(node)
    if mult is not None:
        linked, k = mult
        return _from_socket(linked, tuple(c * x for c, x in zip(colour, k)), name)
    return None, f"'{name}': its colour comes from a {node.bl_idname} node"


def albedo_source(material):
    """The AlbedoSource of a material; anything not read falls back to its viewport colour, with a note."""
    if material is None:
        return AlbedoSource("CONSTANT", (0.8, 0.8, 0.8))
    viewport = tuple(material.diffuse_color)[:3]
    output = active_output(material)
    if output is None or not output.inputs["Surface"].is_linked:
        return AlbedoSource("CONSTANT", viewport)
    shader = output.inputs["Surface"].links[0].from_node
    socket_name = DIFFUSE_INPUTS.get(shader.bl_idname)
    if socket_name is None:
        return _fallback(material, f"'{material.name}': not a diffuse shader")
    socket = shader.inputs[socket_name]
    if not socket.is_linked:
        return AlbedoSource("CONSTANT", _constant(socket))
    source, note = _from_socket(socket, (1.0, 1.0, 1.0), material.name)
    if source is None:
        return AlbedoSource("CONSTANT", viewport, note=note + "; its viewport colour is used")
    image = source.image
    if image is not None and image.source == "TILED":
        return _fallback(material, f"'{material.name}': UDIM tiles are not read")
    return source


def _fallback(material, note):
    return AlbedoSource("CONSTANT", tuple(material.diffuse_color)[:3], note=note + "; its viewport colour is used")


def mesh_source(material, mesh):
    """The AlbedoSource drawn for `material` on `mesh`: albedo_source, with uv_map resolved ("" ->
    the mesh's active render UV map) and the attribute's name; an image on a UV map the mesh lacks,
    an image without pixels or a missing colour attribute fall back to the viewport colour, with a note."""
    src = albedo_source(material)
    if src.kind == "ATTRIBUTE":
        attr = colour_attribute(mesh, src.attribute)
        if attr is None:
            return _fallback(material, f"'{material.name}': '{mesh.name}' has no colour attribute '{src.attribute}'")
        return replace(src, attribute=attr.name)
    if src.kind != "IMAGE":
        return src
    layers = mesh.uv_layers
    if len(layers) == 0:
        return _fallback(material, f"'{material.name}': '{mesh.name}' has no UV map for its image")
    uv_map = src.uv_map
    if not uv_map:
        active = next((layer for layer in layers if layer.active_render), layers[0])
        uv_map = active.name
    if layers.get(uv_map) is None:
        return _fallback(material, f"'{material.name}': '{mesh.name}' has no UV map '{uv_map}'")
    if src.image.size[0] == 0 or src.image.size[1] == 0:
        return _fallback(
            material, f"'{material.name}': image '{src.image.name}' has no pixels (missing or unreadable file)"
        )
    return replace(src, uv_map=uv_map)


def slot_sources(obj):
    """Per material slot of `obj` (at least one entry), mesh_source of its material."""
    materials = [slot.material for slot in obj.material_slots] or [None]
    return [mesh_source(material, obj.data) if material is not None else albedo_source(None) for material in materials]


def colour_space_note(image):
    """The note image_pixels gives for the image's colour space (without reading its pixels)."""
    space = image.colorspace_settings.name
    if space == "Non-Color":
        return f"image '{image.name}' is Non-Color data on a colour input: its values are used as they are"
    if not image.is_float and space not in LINEAR_SPACES and space != "sRGB":
        return f"image '{image.name}': colour space {space} read as sRGB"
    return ""


LINEAR_SPACES = {"Non-Color", "Linear Rec.709", "Linear", "Raw"}


def raw_pixels(image):
    """((h, w, channels) float32 as Blender holds them, row 0 the bottom, ""), or (None, note) when
    the image has no pixels (a missing file)."""
    width, height = image.size
    if width == 0 or height == 0:
        return None, f"image '{image.name}' has no pixels (missing or unreadable file)"
    px = np.empty(width * height * image.channels, dtype=np.float32)
    image.pixels.foreach_get(px)
    return px.reshape(height, width, image.channels), ""


def linear_rgb(image, px):
    """(h, w, 3) RGB of raw_pixels' `px`, a byte image not in a linear space decoded with the sRGB
    curve (as Cycles reads it, whatever the socket), float and linear ones kept."""
    rgb = px[..., :3] if image.channels >= 3 else np.repeat(px[..., :1], 3, axis=2)
    if not image.is_float and image.colorspace_settings.name not in LINEAR_SPACES:
        rgb = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    return rgb


def image_pixels(image):
    """((h, w, 3) float32 scene-linear RGB clamped to [0, 1], row 0 the bottom, note), or (None,
    note) when the image has no pixels (a missing file). Byte sRGB images are decoded with the sRGB
    curve, float and linear ones kept; other colour spaces are read as sRGB, with a note."""
    px, note = raw_pixels(image)
    if px is None:
        return None, note
    rgb = linear_rgb(image, px)
    space = image.colorspace_settings.name
    if not image.is_float and space not in LINEAR_SPACES and space != "sRGB":
        note = f"image '{image.name}': colour space {space} read as sRGB"
    if space == "Non-Color":
        note = f"image '{image.name}' is Non-Color data on a colour input: its values are used as they are"
    if rgb.min() < 0.0 or rgb.max() > 1.0:
        note = (note + "; " if note else "") + f"image '{image.name}': values outside 0 to 1 clamped"
    return np.clip(rgb, 0.0, 1.0).astype(np.float32), note
