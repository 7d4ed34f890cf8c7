"""The display's albedo settings, colour attributes per element, the active Material Output node."""

import numpy as np

from . import mesh_read, storage


def display_settings(scene):
    settings = getattr(scene, "prt_display", None)
    if settings is None:
        return "MATERIAL", ""
    return settings.albedo_source, settings.albedo_attribute


def colour_attribute(mesh, name):
    if name:
        attr = mesh.color_attributes.get(name)
        return attr
    active = mesh.color_attributes.active_color
    if active is not None and not active.name.startswith(storage.PREFIX):
        return active
    for attr in mesh.color_attributes:
        if not attr.name.startswith(storage.PREFIX):
            return attr
    return None


def element_count(mesh, domain):
    return len(mesh.vertices) if domain == "POINT" else len(mesh.loops)


def element_albedo(mesh, domain, mode, attr_name):
    """(elements, 4) float32 per-element albedo factor: ones unless mode == 'ATTRIBUTE'."""
    n = element_count(mesh, domain)
    ones = np.ones((n, 4), dtype=np.float32)
    if mode != "ATTRIBUTE":
        return ones
    attr = colour_attribute(mesh, attr_name)
    if attr is None:
        return ones
    values = np.empty(element_count(mesh, attr.domain) * 4, dtype=np.float32)
    attr.data.foreach_get("color", values)
    values = values.reshape(-1, 4)
    if attr.domain == domain:
        return values
    corner_verts = mesh_read.read_corner_verts(mesh)
    if domain == "CORNER":  # POINT colours onto corners
        return np.ascontiguousarray(values[corner_verts])
    # CORNER colours onto vertices: the mean of each vertex's corners.
    sums = np.zeros((n, 4))
    np.add.at(sums, corner_verts, values)
    counts = np.bincount(corner_verts, minlength=n)[:, None]
    return np.where(counts > 0, sums / np.maximum(counts, 1), 1.0).astype(np.float32)


def active_output(material):
    """The material's active Material Output node, or None (no node tree, or none active)."""
    tree = getattr(material, "node_tree", None)
    for node in tree.nodes if tree is not None else []:
        if node.bl_idname == "ShaderNodeOutputMaterial" and node.is_active_output:
            return node
    return None
