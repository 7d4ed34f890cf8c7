"""Where a Principled BSDF's Roughness, Metallic, Specular IOR Level and IOR come from: a constant or an image."""

from dataclasses import dataclass, replace

import numpy as np

from .albedo_source import EXTENSION_MODES, INTERPOLATION_MODES, LINEAR_SPACES, linear_rgb, raw_pixels
from .materials import active_output

INPUTS = ("Roughness", "Metallic", "Specular IOR Level", "IOR")
# Per input the range its values are clamped to: IOR below 1 is 1, Specular IOR Level and IOR unbounded above.
RANGES = ((0.0, 1.0), (0.0, 1.0), (0.0, np.inf), (1.0, np.inf))
LUMINANCE = -1  # an Image Texture's Color on a float socket: Blender converts it to its luminance
ALPHA = 3
# Rec.709 luminance: Blender's colour -> float conversion in its default (Rec.709) scene space.
LUMA = np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
_SEPARATE = {
    "ShaderNodeSeparateColor": ("Red", "Green", "Blue"),
    "ShaderNodeSeparateRGB": ("R", "G", "B"),
}


@dataclass(frozen=True)
class MapInput:
    """One input read from an image: channel 0-2 (R, G, B), ALPHA or LUMINANCE, times factor, on
    uv_map ("" = the mesh's active render UV map until mesh_maps resolves it), sampled as the
    node's (interpolation, extension) (albedo_source's numbers)."""

    image: object
    channel: int
    factor: float = 1.0
    uv_map: str = ""
    sampling: tuple = (0, 0)


@dataclass(frozen=True)
class SlotMaps:
    """Per INPUTS entry a MapInput or None (the constant); uv_map: the maps' one UV map; notes:
    why a linked input is drawn as its constant, and what its image says."""

    inputs: tuple = (None, None, None, None)
    uv_map: str = ""
    notes: tuple = ()
    f0_per_level: float = 0.08  # ((IOR - 1) / (IOR + 1))^2 x 2 of the constant IOR: the dielectric F0 at level 1
    level: float = 0.5  # the constant Specular IOR Level (at least 0)

    @property
    def any(self):
        return any(m is not None for m in self.inputs)


def _principled(material):
    output = active_output(material) if material is not None else None
    if output is None or not output.inputs["Surface"].is_linked:
        return None
    node = output.inputs["Surface"].links[0].from_node
    return node if node.bl_idname == "ShaderNodeBsdfPrincipled" and not node.mute else None


def _multiply(node):
    """(linked input, constant) of a Math node in Multiply with one constant input, else None."""
    if node.bl_idname != "ShaderNodeMath" or node.operation != "MULTIPLY" or node.mute:
        return None
    a, b = node.inputs[0], node.inputs[1]
    if a.is_linked == b.is_linked:
        return None
    linked, const = (a, b) if a.is_linked else (b, a)
    return linked, float(const.default_value)


def _image_input(node, channel, factor, where):
    if node.image is None:
        return None, f"{where}: its Image Texture node has no image"
    if node.image.source == "TILED":
        return None, f"{where}: UDIM tiles are not read"
    sampling = (INTERPOLATION_MODES.get(node.interpolation, 0), EXTENSION_MODES.get(node.extension, 0))
    vector = node.inputs["Vector"]
    uv_map = ""
    if vector.is_linked:
        uv = vector.links[0].from_node
        if uv.bl_idname != "ShaderNodeUVMap":
            return None, f"{where}: the image's coordinates come from a {uv.bl_idname} node"
        uv_map = uv.uv_map
    return MapInput(node.image, channel, factor, uv_map, sampling), ""


def socket_map(socket, where):
    """(MapInput, "") for a float socket fed by an Image Texture (its Color as luminance, its
    Alpha, or one channel through a Separate Color/RGB node in RGB mode), through Math Multiply
    nodes with a constant; (None, note) for any other link; (None, "") when unlinked."""
    factor, channel = 1.0, None
    while socket.is_linked:
        link = socket.links[0]
        node, out = link.from_node, link.from_socket
        if node.bl_idname == "ShaderNodeTexImage":
            if channel is None:
                channel = ALPHA if out.name == "Alpha" else LUMINANCE
            elif out.name == "Alpha":
                return None, f"{where}: a Separate node on the image's Alpha"
            return _image_input(node, channel, factor, where)
        mult = _multiply(node)
        if mult is not None and channel is None:
            socket, k = mult
            factor *= k
            continue
        names = _SEPARATE.get(node.bl_idname)
        if names is not None and channel is None and getattr(node, "mode", "RGB") == "RGB" and out.name in names:
            channel = names.index(out.name)
            socket = node.inputs[0]
            continue
        return None, f"{where}: it comes from a {node.bl_idname} node"
    return None, ""


def principled_maps(material):
    """The SlotMaps of a material: which of Roughness, Metallic, Specular IOR Level and IOR of the
    Principled BSDF feeding its active output come from an image; every other link is drawn as its
    socket's constant, with a note."""
    node = _principled(material)
    if node is None:
        return SlotMaps()
    inputs, notes = [], []
    for name in INPUTS:
        sock = node.inputs.get(name)
        found, note = (None, "") if sock is None else socket_map(sock, f"'{material.name}' {name}")
        inputs.append(found)
        if note:
            notes.append(note + "; its constant is used")
    ior, level = (_constant(node, name, default) for name, default in (("IOR", 1.5), ("Specular IOR Level", 0.5)))
    ior, level = max(ior, 1.0), max(level, 0.0)
    return SlotMaps(tuple(inputs), "", tuple(notes), ((ior - 1.0) / (ior + 1.0)) ** 2 * 2.0, level)


def _constant(node, name, default):
    sock = node.inputs.get(name)
    return float(sock.default_value) if sock is not None and hasattr(sock, "default_value") else default


def mesh_maps(material, mesh, albedo_uv=None):
    """principled_maps for `material` on `mesh`, each map's UV map resolved ("" -> the active
    render one). A map falls back to its constant, with a note, when the mesh lacks its UV map, its
    image has no pixels, or its UV map differs from the first map's or from `albedo_uv` (the base
    colour image's, when it has one): one UV map per material is drawn."""
    found = principled_maps(material)
    if not found.any:
        return found
    layers = mesh.uv_layers
    active = next((layer for layer in layers if layer.active_render), layers[0] if len(layers) else None)
    inputs, notes, uv_map = [], list(found.notes), albedo_uv
    for name, item in zip(INPUTS, found.inputs):
        if item is None:
            inputs.append(None)
            continue
        where = f"'{material.name}' {name}"
        wanted = item.uv_map or (active.name if active is not None else "")
        if not wanted or layers.get(wanted) is None:
            problem = f"'{mesh.name}' has no UV map" + (f" '{wanted}'" if wanted else "")
        elif item.image.size[0] == 0 or item.image.size[1] == 0:
            problem = f"image '{item.image.name}' has no pixels (missing or unreadable file)"
        elif uv_map is not None and wanted != uv_map:
            problem = f"its image is on UV map '{wanted}', the material's other image on '{uv_map}'"
        else:
            problem = ""
        if problem:
            notes.append(f"{where}: {problem}; its constant is used")
            inputs.append(None)
            continue
        uv_map = wanted
        inputs.append(replace(item, uv_map=wanted))
        space = item.image.colorspace_settings.name
        if not item.image.is_float and space not in LINEAR_SPACES:
            notes.append(f"{where}: image '{item.image.name}' is {space}, read through its curve (Non-Color expected)")
    return SlotMaps(tuple(inputs), uv_map or "", tuple(dict.fromkeys(notes)), found.f0_per_level, found.level)


def map_pixels(image, channel, factor=1.0, upper=1.0, lower=0.0):
    """((h, w) float32 values in [lower, upper], row 0 the bottom, note) of one channel of `image` times
    factor, decoded as the image's colour space says (an 8-bit image not in a linear space through
    the sRGB curve, as Cycles reads it whatever the socket); (None, note) without pixels."""
    px, note = raw_pixels(image)
    if px is None:
        return None, note
    if channel == ALPHA:
        values = px[..., 3] if image.channels == 4 else np.ones(px.shape[:2], np.float32)
    else:
        rgb = linear_rgb(image, px)
        values = rgb @ LUMA if channel == LUMINANCE else rgb[..., channel]
    values = values * np.float32(factor)
    note = ""
    if values.min() < lower or values.max() > upper:
        span = f"below {lower:g}" if np.isinf(upper) else f"outside {lower:g} to {upper:g}"
        note = f"image '{image.name}': values {span} clamped"
    return np.clip(values, lower, upper).astype(np.float32), note
