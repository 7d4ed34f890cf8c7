"""numpy out of Blender meshes: positions, normals, corners, triangles, topology fingerprints.

Reads go through foreach_get into float32/int32 buffers; the geometry itself is computed by
prt_addon.core.transfer.mesh.
"""

import hashlib

import numpy as np

from ...core.transfer.mesh import (
    BakePoints,
    transform_normals,
    transform_points,
    triangle_corners,
    triangulate_quads,
    vertex_normal_pairs,
    vertex_points,
)


def read_positions(mesh):
    out = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    if len(out):
        mesh.attributes["position"].data.foreach_get("vector", out)
    return out.reshape(-1, 3)


def read_vertex_normals(mesh):
    out = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    if len(out):
        mesh.vertex_normals.foreach_get("vector", out)
    return out.reshape(-1, 3)


def read_corner_normals(mesh):
    out = np.empty(len(mesh.loops) * 3, dtype=np.float32)
    if len(out):
        mesh.corner_normals.foreach_get("vector", out)
    return out.reshape(-1, 3)


def read_corner_verts(mesh):
    out = np.empty(len(mesh.loops), dtype=np.int32)
    if len(out):
        attr = mesh.attributes.get(".corner_vert")  # ~200 times faster than mesh.loops
        if attr is not None and attr.data_type == "INT" and attr.domain == "CORNER":
            attr.data.foreach_get("value", out)
        else:
            mesh.loops.foreach_get("vertex_index", out)
    return out


def read_face_starts(mesh):
    out = np.empty(len(mesh.polygons), dtype=np.int32)
    if len(out):
        mesh.polygons.foreach_get("loop_start", out)
    return out


def _tessellation(mesh):
    """(corner vertices, face starts, face sizes, whether every face is a triangle or a quad)."""
    corner_verts = read_corner_verts(mesh)
    starts = read_face_starts(mesh)
    sizes = np.diff(starts, append=np.int32(len(corner_verts)))
    return corner_verts, starts, sizes, len(starts) > 0 and bool(((sizes == 3) | (sizes == 4)).all())


def _loop_triangles(mesh, field):
    """loop_triangles' `field` ('vertices', 'loops' or 'polygon_index') as int32, (T, 3) or (T,)."""
    mesh.calc_loop_triangles()
    width = 1 if field == "polygon_index" else 3
    out = np.empty(len(mesh.loop_triangles) * width, dtype=np.int32)
    if len(out):
        mesh.loop_triangles.foreach_get(field, out)
    return out if width == 1 else out.reshape(-1, 3)


def read_triangles(mesh, positions=None):
    """(T, 3) int32 vertex indices of the mesh's loop triangles, in Blender's order.

    Meshes of triangles and quads are triangulated here as Blender does it (faster than reading
    mesh.loop_triangles, whose foreach_get goes element by element; docs/bake.md); meshes with
    n-gons read loop_triangles. positions: the mesh's vertex positions if already read.
    """
    corner_verts, starts, sizes, quads_only = _tessellation(mesh)
    if not quads_only:
        return _loop_triangles(mesh, "vertices")
    positions = read_positions(mesh) if positions is None else positions
    return triangulate_quads(corner_verts, starts, sizes, positions)


def read_triangle_corners(mesh, positions=None):
    """((T, 3) int32 corner (loop) indices, (T,) int32 face index) of the loop triangles, in the
    order of read_triangles."""
    corner_verts, starts, sizes, quads_only = _tessellation(mesh)
    if not quads_only:
        return _loop_triangles(mesh, "loops"), _loop_triangles(mesh, "polygon_index")
    positions = read_positions(mesh) if positions is None else positions
    faces = np.repeat(np.arange(len(starts), dtype=np.int32), sizes - 2)
    return triangle_corners(corner_verts, starts, sizes, positions), faces


def read_face_materials(mesh):
    out = np.zeros(len(mesh.polygons), dtype=np.int32)
    if len(out):
        attr = mesh.attributes.get("material_index")  # (absent: every face uses slot 0)
        if attr is not None and attr.data_type == "INT" and attr.domain == "FACE":
            attr.data.foreach_get("value", out)  # ~100 times faster than mesh.polygons
        elif attr is not None:
            mesh.polygons.foreach_get("material_index", out)
    return out


def topology_fingerprint(mesh):
    """'V:E:F:L:hash' of the vertex, edge, face and corner counts and the corner/face layout."""
    h = hashlib.blake2b(digest_size=8)
    h.update(read_corner_verts(mesh).tobytes())
    h.update(read_face_starts(mesh).tobytes())
    return f"{len(mesh.vertices)}:{len(mesh.edges)}:{len(mesh.polygons)}:{len(mesh.loops)}:{h.hexdigest()}"


def bake_points(mesh, matrix4, positions=None):
    """BakePoints of an (evaluated) mesh whose topology matches the mesh being written.

    Domain: POINT when every vertex has a single normal over all its corners (mesh.normals_domain
    is POINT: all faces smooth, no sharp edges, no custom normals; or e.g. a flat plane, whose
    corners at a vertex all share the face normal up to NORMAL_TOLERANCE), else CORNER.
    positions: the mesh's local vertex positions if already read (read_positions).
    """
    positions = read_positions(mesh) if positions is None else positions
    if mesh.normals_domain == "POINT":
        return vertex_points(matrix4, positions, read_vertex_normals(mesh))
    # Corners that share a vertex and a normal (smooth regions) get the same transfer: bake once.
    vert, normals, inverse = vertex_normal_pairs(read_corner_verts(mesh), read_corner_normals(mesh), len(positions))
    if np.array_equal(vert, np.arange(len(positions))):  # sorted: exactly one normal each
        return vertex_points(matrix4, positions, normals)
    return BakePoints(
        "CORNER",
        transform_points(matrix4, positions[vert]),
        transform_normals(matrix4, normals),
        inverse.astype(np.int64),
        vert.astype(np.int64),
    )


def uv_map_names(mesh):
    """The names of the mesh's UV maps, in order."""
    return [layer.name for layer in mesh.uv_layers]


def read_corner_uvs(mesh, uv_name):
    """(corners, 2) float32 UVs of the UV map `uv_name` (a FLOAT2 corner attribute)."""
    out = np.empty(len(mesh.loops) * 2, dtype=np.float32)
    if len(out):
        mesh.attributes[uv_name].data.foreach_get("vector", out)
    return out.reshape(-1, 2)


def uv_fingerprint(mesh, uv_name):
    """A hash of the UV map's coordinates: a texel bake is stale once they change."""
    h = hashlib.blake2b(digest_size=8)
    h.update(np.ascontiguousarray(read_corner_uvs(mesh, uv_name), dtype=np.float32).tobytes())
    return h.hexdigest()


def world_triangles(mesh, matrix4, positions=None):
    """The loop triangles with their corners, for a texel bake: (corners (T, 3) loop indices,
    vertices (T, 3), world positions (T, 3, 3), world unit corner normals (T, 3, 3))."""
    positions = read_positions(mesh) if positions is None else positions
    corners, _faces = read_triangle_corners(mesh, positions)
    vertices = read_corner_verts(mesh)[corners]
    world = transform_points(matrix4, positions)[vertices]
    normals = transform_normals(matrix4, read_corner_normals(mesh))[corners]
    return corners, vertices, world, normals
