"""The contact tangent per vertex in a .glb (`_PRT_CONTACT`): written for the exporter, then stored as normalised bytes.

A viewer's shadow-map lookups move along it, off a surface that touches the receiver, as the
viewport's do (display/shader_suns.py, docs/display.md "Joins"). The tangent is the bake's
(core.transfer.contact.inward_tangents of the mesh's own positions, in the bake's domain: vertex
normals for POINT, corner normals for CORNER and TEXEL, as display/gpu_cache.py builds `prt_tan`),
rotated into glTF's frame. Blender's exporter writes a FLOAT_VECTOR attribute as a VEC3 FLOAT
accessor as it is (custom attributes are not turned to Y up); `store` rewrites those accessors as
normalised BYTE VEC4 (x, y, z, 0: a component is q / 127, glTF's rule, no decode table; four
components, as the transfer's, because Blender's importer fails on custom attributes of
different widths in one mesh), and names the attribute in the mesh's extras (`contact`).
docs/export.md ("Contact tangent") is the format.
"""

import numpy as np

from ...core.transfer.contact import inward_tangents
from ..scene import mesh_read
from . import quantise

ATTRIBUTE = "_PRT_CONTACT"
BYTE = 5120
K = 127  # glTF's normalised signed byte: q / 127


def tangents(mesh, domain):
    """(elements, 3) contact tangents of `mesh` in the bake's domain ("POINT", "CORNER" or
    "TEXEL", which is per corner), Blender's local frame."""
    positions = mesh_read.read_positions(mesh)
    triangles = mesh_read.read_triangles(mesh, positions)
    if domain == "POINT":
        return inward_tangents(positions, mesh_read.read_vertex_normals(mesh), positions, triangles)
    corner_verts = mesh_read.read_corner_verts(mesh)
    normals = mesh_read.read_corner_normals(mesh)
    return inward_tangents(positions[corner_verts], normals, positions, triangles, corner_verts)


def add_attribute(mesh, bake, added, to_gltf):
    """Write the mesh's contact tangents, rotated by `to_gltf` (3x3, Blender -> glTF), as the
    FLOAT_VECTOR attribute ATTRIBUTE in the bake's domain (CORNER for a texel bake), appending its
    name to `added`; raises ValueError when the mesh already has one of that name."""
    if mesh.attributes.get(ATTRIBUTE) is not None:
        raise ValueError(f"mesh '{mesh.name}' already has an attribute '{ATTRIBUTE}'; rename it to export")
    rows = tangents(mesh, bake.domain) @ np.asarray(to_gltf, dtype=np.float64).T
    added.append(ATTRIBUTE)
    mesh.attributes.new(ATTRIBUTE, "FLOAT_VECTOR", "POINT" if bake.domain == "POINT" else "CORNER")
    mesh.attributes[ATTRIBUTE].data.foreach_set("vector", np.ascontiguousarray(rows, dtype=np.float32).ravel())


def encode(rows):
    """(count, 4) int8 of float tangent rows (count, 3): round(clip(t, -1, 1) * 127), then 0."""
    q = np.zeros((len(rows), 4), dtype=np.int8)
    q[:, :3] = np.rint(np.clip(np.asarray(rows, dtype=np.float64), -1.0, 1.0) * K)
    return q


def store(document, chunks, extras_key):
    """Rewrite the ATTRIBUTE accessors of the baked meshes (the JSON dict, the chunks after the
    JSON one, BIN first) as normalised BYTE VEC4 and set each such mesh's extras `contact`;
    returns the new chunks (document changed in place)."""
    binary = chunks[0][1]
    accessors = document.get("accessors", [])
    jobs, payloads = [], []
    for mesh in document.get("meshes", []):
        meta = (mesh.get("extras") or {}).get(extras_key)
        prims = [p for p in mesh.get("primitives", []) if ATTRIBUTE in p.get("attributes", {})]
        if not isinstance(meta, dict) or not prims:
            continue
        for index in sorted({p["attributes"][ATTRIBUTE] for p in prims}):
            jobs.append(index)
            payloads.append(encode(quantise.read_float(document, binary, accessors[index], 3)).tobytes())
        meta["contact"] = ATTRIBUTE
    if not jobs:
        return chunks
    replaced = {accessors[i]["bufferView"] for i in jobs}
    others = {a["bufferView"] for i, a in enumerate(accessors) if i not in set(jobs) and "bufferView" in a}
    if replaced & others:
        raise ValueError("a contact tangent's buffer view is shared with other data")
    chunks, views = quantise.pack_views(document, chunks, replaced, payloads)
    for index, view in zip(jobs, views):
        accessor = accessors[index]
        accessor.update(bufferView=view, byteOffset=0, componentType=BYTE, normalized=True, type="VEC4")
        accessor.pop("min", None)
        accessor.pop("max", None)
    return chunks
