"""GPU data of baked meshes (vertex buffers, batches, transfer textures), cached per mesh and bake.

Uploaded once per mesh and bake, and again whenever the evaluated positions of an object deformed
by modifiers or shape keys move (their batches are cached per object).
"""

import gpu
import numpy as np

from ...core.transfer.contact import inward_tangents
from .. import caches
from ..scene import back_storage, mesh_read, storage, texel_storage
from ..scene.materials import element_albedo, element_count
from .shader import shader_mode, transfer_vec4s


class MeshEntry:
    """GPU data of one baked mesh: vertex buffer, one batch per material slot, transfer texture."""

    def __init__(self, key, batches, texture, per_row, evaluated, texel_grid=None, textured=False):
        self.key = key
        self.textured = textured  # drawn per corner with the albedo's UVs (albedo_texture)
        self.batches = batches  # list of (material_index, GPUBatch)
        self.texture = texture
        self.per_row = per_row
        self.texel_grid = texel_grid  # (texels per side, tiles per row) of a texel bake, else None
        self.evaluated = evaluated  # the evaluated positions it was built for (deformed objects)
        self.back_texture = None  # (tiles texture, tiles per row) of a texel bake's back side, else None
        self.points = None  # the vertex buffer as points, one a vertex (spec_occlusion's pass)
        self.vertices = 0


class ObjectState:
    __slots__ = (
        "ubo",
        "light_key",
        "suns_ubo",
        "suns_bytes",
        "relit",
        "relit_key",
        "spec_ubo",
        "spec_bytes",
        "spec_occ",
        "spec_seen",
    )

    def __init__(self):
        self.relit = None  # texel_relight.Relit of a texel bake
        self.relit_key = None  # the light and the entry it was relit for
        self.ubo = None
        self.light_key = None
        self.suns_ubo = None
        self.suns_bytes = None
        self.spec_ubo = None
        self.spec_bytes = None
        self.spec_occ = None  # material slot -> spec_occlusion.Occlusion
        self.spec_seen = None  # material slot -> what its occlusion depended on at the last draw


_mesh_cache = {}  # (mesh pointer, object pointer or 0 when undeformed) -> MeshEntry


_object_cache = {}  # object pointer -> ObjectState


@caches.on_clear
def clear_caches():
    _mesh_cache.clear()
    _object_cache.clear()


@caches.on_geometry
def forget_mesh(mesh):
    """Drop the batches of `mesh` (its geometry changed)."""
    ptr = mesh.as_pointer()
    for key in [k for k in _mesh_cache if k[0] == ptr]:
        del _mesh_cache[key]


def _cache_key(mesh, info, albedo_mode, albedo_attr, sources=None, map_uvs=()):
    record = info.record
    rec = record.to_dict() if hasattr(record, "to_dict") else dict(record)
    return (
        repr(sorted((k, repr(v)) for k, v in rec.items())),
        len(mesh.vertices),
        len(mesh.loops),
        len(mesh.polygons),
        albedo_mode,
        albedo_attr,
        tuple((s.kind, s.uv_map, s.attribute) for s in sources or ()),
        tuple(map_uvs),
    )


def textured(sources, map_uvs=()):
    """Whether slot sources (albedo_source.slot_sources), or the slots' Principled maps on the UV
    maps `map_uvs` (material_maps.uv_maps), need the per-corner albedo draw."""
    return any(s.kind != "CONSTANT" for s in sources or ()) or any(map_uvs)


def corner_albedo(mesh, sources, map_uvs=()):
    """((corners, 4) albedo factor, (corners, 2) UVs) per corner from each face's slot source:
    the colour attribute of an ATTRIBUTE slot, the UV map of an IMAGE slot or of a slot's
    Principled maps (map_uvs); ones and zeros elsewhere."""
    n = len(mesh.loops)
    albedo = np.ones((n, 4), dtype=np.float32)
    uvs = np.zeros((n, 2), dtype=np.float32)
    starts = mesh_read.read_face_starts(mesh)
    sizes = np.diff(starts, append=np.int32(n))
    slot = np.repeat(np.clip(mesh_read.read_face_materials(mesh), 0, len(sources) - 1), sizes)
    for i, src in enumerate(sources):
        here = slot == i
        uv_map = src.uv_map if src.kind == "IMAGE" else (map_uvs[i] if i < len(map_uvs) else "")
        if src.kind == "ATTRIBUTE" and here.any():
            albedo[here] = element_albedo(mesh, "CORNER", "ATTRIBUTE", src.attribute)[here]
        if uv_map and here.any():
            uvs[here] = mesh_read.read_corner_uvs(mesh, uv_map)[here]
    return albedo, uvs


def read_transfer(mesh, info):
    """(elements, 4 * vec4s) float32: the direct transfer t_0 .. t_{4 count - 1} per element
    (padding channels 0), then each bounce channel's, then the back side's, padded the same
    (shader.transfer_vec4s)."""
    parts = [storage.read_transfer(mesh, info, padded=True)]
    bounced = storage.read_bounce(mesh, info, padded=True)
    if bounced is not None:
        parts.append(bounced.reshape(len(bounced), -1))
    if info.back:
        parts.append(back_storage.read_back(mesh, info.count, info.order, padded=True))
    return parts[0] if len(parts) == 1 else np.ascontiguousarray(np.concatenate(parts, axis=1))


def deformed_mesh(obj, depsgraph):
    """obj's evaluated mesh when its modifiers or shape keys may move its vertices and keep the
    element counts (what the viewport shows, and what the bake used), else None: the mesh's
    own positions are drawn (no deformation; no depsgraph; or other counts, which the bake
    refuses, e.g. a Subdivision added after baking). get_mesh_entry also compares the full
    topology before it draws these positions."""
    mesh = obj.data
    if depsgraph is None or not (mesh.shape_keys or any(m.show_viewport for m in obj.modifiers)):
        return None
    mesh_eval = obj.evaluated_get(depsgraph).data
    counts = (len(mesh.vertices), len(mesh.loops), len(mesh.polygons))
    if (len(mesh_eval.vertices), len(mesh_eval.loops), len(mesh_eval.polygons)) != counts:
        return None
    return mesh_eval


def element_normals(mesh, domain):
    """(elements, 3) float32 local normals in the bake's domain: vertex or corner normals."""
    if domain == "CORNER":
        return mesh_read.read_corner_normals(mesh)
    return mesh_read.read_vertex_normals(mesh)


def build_mesh_entry(
    mesh,
    info,
    key,
    albedo_mode="MATERIAL",
    albedo_attr="",
    positions=None,
    evaluated=None,
    normals=None,
    sources=None,
    map_uvs=(),
):
    """Upload a baked mesh: vertex buffer per element, index buffers per material, transfer.
    key: its _cache_key; positions: (vertices, 3) local positions to draw instead of the mesh's
    (deformed_mesh), with normals their (elements, 3) normals; evaluated: the evaluated positions
    the entry stands for (get_mesh_entry); sources: the slots' AlbedoSources in Material mode. A
    mesh with an image or attribute slot is drawn per corner (a vertex bake's elements copied to
    its corners), with each corner's albedo and UV; map_uvs: per slot the UV map of its Principled
    maps ("" none; material_maps.uv_maps), which make it drawn per corner too."""
    per_corner = textured(sources, map_uvs) and info.domain == "POINT"
    if per_corner and normals is None:
        normals = element_normals(mesh, "POINT")
    domain = "POINT" if info.domain == "POINT" and not per_corner else "CORNER"  # (texel bakes: UVs per corner)
    n = element_count(mesh, domain)
    if positions is None:
        positions = mesh_read.read_positions(mesh)
    if normals is None:
        normals = element_normals(mesh, domain)
    mesh.calc_loop_triangles()
    ntri = len(mesh.loop_triangles)
    tris = np.empty(ntri * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("loops" if domain == "CORNER" else "vertices", tris)
    tris = tris.reshape(-1, 3)
    mat_index = np.empty(ntri, dtype=np.int32)
    mesh.loop_triangles.foreach_get("material_index", mat_index)
    # The bake's contact tangents per element: the sun shader moves its shadow-map lookups along
    # them, off a surface that touches this one (shader_suns.py; docs/display.md, "Joins").
    if per_corner:
        corner_verts = mesh_read.read_corner_verts(mesh)
        tangents = inward_tangents(positions, normals, positions, corner_verts[tris])[corner_verts]
        positions, normals = positions[corner_verts], normals[corner_verts]
    elif domain == "CORNER":
        corner_verts = mesh_read.read_corner_verts(mesh)
        tangents = inward_tangents(positions[corner_verts], normals, positions, corner_verts[tris], corner_verts)
        positions = np.ascontiguousarray(positions[corner_verts])
    else:
        tangents = inward_tangents(positions, normals, positions, tris)
    uvs = None
    if textured(sources, map_uvs):
        albedo, uvs = corner_albedo(mesh, sources, map_uvs)
    else:
        albedo = element_albedo(mesh, domain, albedo_mode, albedo_attr)

    vec4s = transfer_vec4s(info.count, info.channels, info.back)
    mode = shader_mode(vec4s, info.domain, uvs is not None)
    transfer = None if mode == "TEXEL" else read_transfer(mesh, info)
    if per_corner:
        transfer = np.ascontiguousarray(transfer[corner_verts])
    fmt = gpu.types.GPUVertFormat()
    fmt.attr_add(id="prt_pos", comp_type="F32", len=3, fetch_mode="FLOAT")
    fmt.attr_add(id="prt_albedo", comp_type="F32", len=4, fetch_mode="FLOAT")
    fmt.attr_add(id="prt_nrm", comp_type="F32", len=3, fetch_mode="FLOAT")
    fmt.attr_add(id="prt_tan", comp_type="F32", len=3, fetch_mode="FLOAT")
    if mode == "ATTR":
        for k in range(vec4s):
            fmt.attr_add(id=f"prt_t{k}", comp_type="F32", len=4, fetch_mode="FLOAT")
    elif mode == "TEXEL":
        fmt.attr_add(id="prt_uv", comp_type="F32", len=2, fetch_mode="FLOAT")
    if uvs is not None:
        fmt.attr_add(id="prt_albedo_uv", comp_type="F32", len=2, fetch_mode="FLOAT")
    vbo = gpu.types.GPUVertBuf(fmt, n)
    vbo.attr_fill("prt_pos", positions)
    vbo.attr_fill("prt_albedo", albedo)
    vbo.attr_fill("prt_nrm", np.ascontiguousarray(normals, dtype=np.float32))
    vbo.attr_fill("prt_tan", tangents.astype(np.float32))
    if uvs is not None:
        vbo.attr_fill("prt_albedo_uv", uvs)
    texture, per_row, grid, back = None, 0, None, None
    if mode == "ATTR":
        for k in range(vec4s):
            vbo.attr_fill(f"prt_t{k}", np.ascontiguousarray(transfer[:, 4 * k : 4 * k + 4]))
    elif mode == "TEXEL":
        vbo.attr_fill("prt_uv", np.ascontiguousarray(mesh_read.read_corner_uvs(mesh, info.uv_map)))
        texture, grid = _texel_texture(info.image, info.resolution, texel_storage.total_groups(info))
        back = _texel_texture(info.back_image, info.resolution, info.count) if info.back_image else None
    else:
        texture, per_row = _transfer_texture(transfer, vec4s)

    batches = []
    if ntri:
        order_idx = np.argsort(mat_index, kind="stable")
        sorted_mat = mat_index[order_idx]
        starts = np.flatnonzero(np.r_[True, sorted_mat[1:] != sorted_mat[:-1]])
        ends = np.r_[starts[1:], ntri]
        for s, e in zip(starts, ends):
            seq = np.ascontiguousarray(tris[order_idx[s:e]])
            ibo = gpu.types.GPUIndexBuf(type="TRIS", seq=seq)
            batches.append((int(sorted_mat[s]), gpu.types.GPUBatch(type="TRIS", buf=vbo, elem=ibo)))
    entry = MeshEntry(key, batches, texture, per_row, evaluated, grid, uvs is not None)
    entry.back_texture = None if back is None else (back[0], back[1][1])
    entry.points, entry.vertices = gpu.types.GPUBatch(type="POINTS", buf=vbo), n
    return entry


def _texel_texture(image, resolution, groups):
    """A texel bake's transfer image of `groups` tiles as an RGBA32F texture, and its grid."""
    pixels = texel_storage.read_pixels(image)
    height, width = pixels.shape[:2]
    buf = gpu.types.Buffer("FLOAT", pixels.size, np.ascontiguousarray(pixels).reshape(-1))
    tex = gpu.types.GPUTexture((width, height), format="RGBA32F", data=buf)
    return tex, (resolution, texel_storage.tile_grid(groups)[0])


def _transfer_texture(transfer, count):
    """RGBA32F texture, element e's k-th vec4 at texel ((e % per_row) * count + k, e // per_row)."""
    n = transfer.shape[0]
    max_size = min(16384, gpu.capabilities.max_texture_size_get())
    per_row = max(1, min(max_size // count, n))
    rows = max(1, -(-n // per_row))
    if rows > max_size:
        raise RuntimeError(f"{n} elements at {count} texels each exceed one {max_size}x{max_size} texture")
    data = np.zeros((rows * per_row * count, 4), dtype=np.float32)
    data[: n * count] = transfer.reshape(n * count, 4)
    buf = gpu.types.Buffer("FLOAT", data.size, data.reshape(-1))
    tex = gpu.types.GPUTexture((per_row * count, rows), format="RGBA32F", data=buf)
    return tex, per_row


def get_mesh_entry(mesh, info, albedo_mode, albedo_attr, obj=None, depsgraph=None, sources=None, map_uvs=()):
    """The cached batches of `mesh`, or of `obj` when its modifiers or shape keys deform it:
    those are drawn at their evaluated positions, read again at every draw; when they moved (an
    animated armature, a shape-key value being dragged) the whole entry is built again.
    sources: the slots' AlbedoSources (Material mode) and map_uvs (build_mesh_entry), part of the
    cache key."""
    mesh_eval = None if obj is None else deformed_mesh(obj, depsgraph)
    positions = None if mesh_eval is None else mesh_read.read_positions(mesh_eval)
    ptr = (mesh.as_pointer(), 0 if positions is None else obj.as_pointer())
    key = _cache_key(mesh, info, albedo_mode, albedo_attr, sources, map_uvs)
    entry = _mesh_cache.get(ptr)
    if entry is None or entry.key != key or (positions is not None and not np.array_equal(entry.evaluated, positions)):
        drawn, normals = positions, None
        # Same counts but other connectivity (e.g. a Sort Elements node): the baked elements
        # are not these, so draw the undeformed mesh.
        if positions is not None and mesh_read.topology_fingerprint(mesh_eval) != mesh_read.topology_fingerprint(mesh):
            drawn = None
        if drawn is not None:
            normals = element_normals(mesh_eval, info.domain)
        entry = build_mesh_entry(mesh, info, key, albedo_mode, albedo_attr, drawn, positions, normals, sources, map_uvs)
        _mesh_cache[ptr] = entry
    return entry


def _prune(objects, slack=8):
    """Drop cached GPU data of meshes and objects no longer drawn (deleted, undone, hidden)."""
    if len(_mesh_cache) + len(_object_cache) <= 2 * len(objects) + slack:
        return
    meshes = {obj.data.as_pointer() for obj in objects}
    objs = {obj.as_pointer() for obj in objects}
    for key in [k for k in _mesh_cache if k[0] not in meshes or (k[1] and k[1] not in objs)]:
        del _mesh_cache[key]
    for key in [k for k in _object_cache if k not in objs]:
        del _object_cache[key]
