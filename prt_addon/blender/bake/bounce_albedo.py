"""The albedo light bounces off: each triangle's diffuse colour from its material (linear RGB).

The rule is the display's Material albedo (display/albedo.py): the Principled BSDF's Base Color or
the Diffuse BSDF's Color, else the material's viewport colour (no material: 0.8 grey, Blender's
default surface). A colour that comes from an Image Texture node is the image's mean colour
(linear); from any other node, the viewport colour; both are said in the report. Values above 1
(an energy gain) are clamped to 1, with a warning. Emission is not light for the bake.
"""

import numpy as np

from ..display.albedo import material_colour
from .. import mesh_read

DEFAULT_GREY = 0.8


def _srgb_to_linear(c):
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _image_mean(image):
    """Mean linear RGB of an image's pixels, or None when it has none."""
    try:
        count = image.size[0] * image.size[1]
        if count == 0:
            return None
        px = np.empty(count * image.channels, dtype=np.float32)
        image.pixels.foreach_get(px)
    except (RuntimeError, ReferenceError, AttributeError):
        return None
    px = px.reshape(-1, image.channels)
    rgb = px[:, :3] if image.channels >= 3 else np.repeat(px[:, :1], 3, axis=1)
    if not image.is_float and image.colorspace_settings.name == "sRGB":
        rgb = _srgb_to_linear(rgb)
    return tuple(float(x) for x in np.mean(rgb, axis=0))


def _linked_colour(material):
    """(colour, note) when the base colour socket is linked, else None."""
    tree = getattr(material, "node_tree", None)
    if tree is None:
        return None
    for node in tree.nodes:
        if node.bl_idname == "ShaderNodeOutputMaterial" and node.is_active_output:
            surface = node.inputs["Surface"]
            if not surface.is_linked:
                return None
            bsdf = surface.links[0].from_node
            sock = bsdf.inputs.get("Base Color") or bsdf.inputs.get("Color")
            if sock is None or not sock.is_linked:
                return None
            source = sock.links[0].from_node
            image = getattr(source, "image", None) if source.bl_idname == "ShaderNodeTexImage" else None
            mean = _image_mean(image) if image is not None else None
            if mean is not None:
                return mean, f"'{material.name}': bounced light uses the mean colour of its image '{image.name}'"
            colour = tuple(material.diffuse_color)[:3]
            return colour, f"'{material.name}': its colour comes from nodes; bounced light uses its viewport colour"
    return None


def slot_colours(obj, notes, seen):
    """(slots, 3) linear RGB per material slot of `obj` (at least one row), notes appended once."""
    colours = []
    for slot in getattr(obj, "material_slots", []):
        material = slot.material
        linked = _linked_colour(material) if material is not None else None
        if linked is not None:
            colour, note = linked
            if note not in seen:
                seen.add(note)
                notes.append(note)
        else:
            colour = material_colour(material)[:3] if material is not None else (DEFAULT_GREY,) * 3
        colours.append(colour)
    if not colours:
        colours.append((DEFAULT_GREY,) * 3)
    return np.asarray(colours, dtype=np.float64)


def triangle_albedo(obj, mesh, faces, notes, seen):
    """(T, 3) albedo of the loop triangles whose faces are `faces`, clamped to [0, 1]."""
    colours = slot_colours(obj, notes, seen)
    over = colours.max() > 1.0 or colours.min() < 0.0
    if over:
        note = f"'{obj.name}': a material colour outside 0 to 1 was clamped (an albedo above 1 would add energy)"
        if note not in seen:
            seen.add(note)
            notes.append(note)
    colours = np.clip(colours, 0.0, 1.0)
    slots = np.clip(mesh_read.read_face_materials(mesh), 0, len(colours) - 1)
    return colours[slots[faces]]
