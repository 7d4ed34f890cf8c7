"""The albedo light bounces off: each triangle's diffuse colour from its material (linear RGB).

The rule is the display's Material albedo (scene/materials.py) for diffuse shaders: the
Principled BSDF's Base Color or the Diffuse BSDF's Color; no material: 0.8 grey (Blender's
default surface); no node tree: the material's viewport colour. A colour that comes from an
Image Texture node on a UV map the mesh has (the display's rule, scene/albedo_source.py) is the
image at each ray's hit point (triangle_images: linear, times the source's colour; the
per-triangle table holds the source's colour there, which every hit replaces); other images
their mean colour; any other node, the viewport colour.
A surface whose shader is not diffuse (Glossy, Glass, ...) reflects with its viewport colour, and
an Emission shader alone reflects nothing (emission is not light for the bake). The report says
which materials were read these ways. Values above 1 (an energy gain) are clamped to 1, with a
warning.
"""

import numpy as np

from ..scene import mesh_read
from ..scene.albedo_source import image_pixels, mesh_source
from ..scene.materials import active_output, element_albedo

DEFAULT_GREY = 0.8
DIFFUSE_SHADERS = {"ShaderNodeBsdfPrincipled": "Base Color", "ShaderNodeBsdfDiffuse": "Color"}
MEAN_BLOCK = 1 << 20  # pixels linearised at a time (float32 temporaries of a few MB)


def _srgb_to_linear(c):
    c = np.asarray(c, dtype=np.float32)
    return np.where(c <= 0.04045, c / np.float32(12.92), ((c + np.float32(0.055)) / np.float32(1.055)) ** 2.4)


def _image_mean(image):
    """Mean linear RGB of an image's pixels, or None when it has none."""
    try:
        count = image.size[0] * image.size[1]
        channels = image.channels
        if count == 0:
            return None
        px = np.empty(count * channels, dtype=np.float32)
        image.pixels.foreach_get(px)
    except (RuntimeError, ReferenceError, AttributeError):
        return None
    px = px.reshape(-1, channels)
    srgb = not image.is_float and image.colorspace_settings.name == "sRGB"
    total = np.zeros(3)
    for a in range(0, count, MEAN_BLOCK):
        block = px[a : a + MEAN_BLOCK, :3] if channels >= 3 else np.repeat(px[a : a + MEAN_BLOCK, :1], 3, axis=1)
        total += (_srgb_to_linear(block) if srgb else block).sum(axis=0, dtype=np.float64)
    return tuple(float(x) for x in total / count)


def _viewport(material):
    return tuple(material.diffuse_color)[:3]


def material_albedo(material, means):
    """(linear RGB, note or "") of a material for bounced light; means caches image means."""
    if material is None:
        return (DEFAULT_GREY,) * 3, ""
    output = active_output(material)
    if output is None:
        return _viewport(material), ""
    surface = output.inputs["Surface"]
    if not surface.is_linked:
        return (0.0, 0.0, 0.0), ""  # no surface: Cycles draws it black and it reflects nothing
    shader = surface.links[0].from_node
    if shader.bl_idname == "ShaderNodeEmission":
        return (0.0, 0.0, 0.0), f"'{material.name}': an Emission shader reflects nothing (emission is not light here)"
    socket_name = DIFFUSE_SHADERS.get(shader.bl_idname)
    if socket_name is None:
        return _viewport(material), f"'{material.name}': not a diffuse shader; bounced light uses its viewport colour"
    socket = shader.inputs[socket_name]
    if not socket.is_linked:
        return tuple(socket.default_value)[:3], ""
    source = socket.links[0].from_node
    image = getattr(source, "image", None) if source.bl_idname == "ShaderNodeTexImage" else None
    if image is not None:
        key = image.as_pointer()
        if key not in means:
            means[key] = _image_mean(image)
        if means[key] is not None:
            return means[key], f"'{material.name}': bounced light uses the mean colour of its image '{image.name}'"
    return _viewport(material), f"'{material.name}': its colour comes from nodes; bounced light uses the viewport one"


def slot_colours(obj, notes, seen, means, quiet=()):
    """(slots, 3) linear RGB per material slot of `obj` (at least one row), notes appended once
    (but not for the slots in `quiet`, which the caller reads per triangle)."""
    colours = []
    for i, slot in enumerate(getattr(obj, "material_slots", [])):
        colour, note = material_albedo(slot.material, means)
        if i not in quiet:
            _say(note, notes, seen)
        colours.append(colour)
    if not colours:
        colours.append((DEFAULT_GREY,) * 3)
    return np.asarray(colours, dtype=np.float64)


def _say(note, notes, seen):
    if note and note not in seen:
        seen.add(note)
        notes.append(note)


def _pixels(src, means):
    """(linear (H, W, 3) pixels or None, note) of src's image, read once per image into `means`."""
    key = ("pixels", src.image.as_pointer())
    if key not in means:
        means[key] = image_pixels(src.image)
    return means[key]


def _image_triangles(src, here, means):
    """(here.sum(), 3) those triangles' entries in the per-triangle table, src's colour (each hit
    looks the image up instead: triangle_images), or None when the image has no pixels."""
    rgb, note = _pixels(src, means)
    if rgb is None:
        return None, note
    return np.tile(np.asarray(src.colour, np.float64), (int(here.sum()), 1)), note


def _slot_triangles(src, mesh, corners, here, means):
    """((here.sum(), 3) albedo of those triangles from an IMAGE or ATTRIBUTE source, or None, note)."""
    if src.kind == "IMAGE":
        values, note = _image_triangles(src, here, means)
        if values is not None:
            note = f"'{src.image.name}': bounced light uses the image at each hit"
        return values, note
    colours = element_albedo(mesh, "CORNER", "ATTRIBUTE", src.attribute)[:, :3]
    values = colours[corners[here]].mean(axis=1) * np.asarray(src.colour)
    return values, f"colour attribute '{src.attribute}': bounced light uses its mean per triangle"


def triangle_albedo(obj, mesh, faces, notes, seen, means, corners=None):
    """(T, 3) albedo of the loop triangles whose faces are `faces` (corners: their (T, 3) corner
    indices), clamped to [0, 1]. A slot whose colour is an image on a UV map the mesh has
    (albedo_source.mesh_source) takes the source's colour (its hits look the image up:
    triangle_images); one whose colour is a colour attribute, the mean of the triangle's corners."""
    slots = mesh_read.read_face_materials(mesh)[faces]
    sources = {}
    if corners is not None:
        for i, slot in enumerate(getattr(obj, "material_slots", [])):
            src = mesh_source(slot.material, mesh) if slot.material is not None else None
            if src is not None and src.kind in ("IMAGE", "ATTRIBUTE"):
                sources[i] = src
    colours = slot_colours(obj, notes, seen, means, quiet=set(sources))
    if colours.max() > 1.0 or colours.min() < 0.0:
        _say(
            f"'{obj.name}': a material colour outside 0 to 1 was clamped (an albedo above 1 would add energy)",
            notes,
            seen,
        )
    colours = np.clip(colours, 0.0, 1.0)
    slots = np.clip(slots, 0, len(colours) - 1)
    albedo = colours[slots]
    for i, src in sources.items():
        here = slots == i
        if not here.any():
            continue
        values, note = _slot_triangles(src, mesh, corners, here, means)
        if values is not None:
            albedo[here] = np.clip(values, 0.0, 1.0)
        _say(note, notes, seen)
    return albedo


def triangle_images(obj, mesh, faces, corners, means):
    """[(local triangle indices, (k, 3, 2) corner UVs, (H, W, 3) linear image times colour, the
    node's sampling, key)] of the loop triangles (faces, corners as triangle_albedo's) whose slot
    shows an image on a UV map the mesh has: what core.transfer.hit_albedo looks up at each hit;
    key: the same for every instance of that slot (image, colour and sampling)."""
    slots = np.clip(mesh_read.read_face_materials(mesh)[faces], 0, max(len(obj.material_slots) - 1, 0))
    out = []
    for i, slot in enumerate(getattr(obj, "material_slots", [])):
        src = mesh_source(slot.material, mesh) if slot.material is not None else None
        if src is None or src.kind != "IMAGE":
            continue
        here = np.flatnonzero(slots == i)
        rgb = _pixels(src, means)[0]
        if len(here) and rgb is not None:
            uvs = mesh_read.read_corner_uvs(mesh, src.uv_map)[corners[here]]
            tinted = ("tinted", src.image.as_pointer(), tuple(src.colour), src.sampling)
            if tinted not in means:  # (one array per image, colour and sampling, however many instances)
                means[tinted] = np.asarray(rgb, np.float32) * np.asarray(src.colour, np.float32)
            out.append((here, uvs, means[tinted], src.sampling, tinted))
    return out
