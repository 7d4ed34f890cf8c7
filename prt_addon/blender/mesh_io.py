"""numpy in and out of Blender meshes for the transfer bake (storage contract: docs/storage.md).

Reading: positions, normals, corners and triangles with foreach_get into float32/int32 buffers.
Writing: the FLOAT_COLOR attributes `prt_tKK` and the record mesh["prt_bake"], all meshes of a
bake at once or none (write_bakes restores the previous state if anything fails).

Attribute references dangle once another attribute is added or removed (the layers are
reallocated), so every access below looks the attribute up by name.
"""

import hashlib
import re
from dataclasses import dataclass

import numpy as np

from ..core.serial_blas import matmul_serial

PREFIX = "prt_t"
RECORD = "prt_bake"
FORMAT_VERSION = 1
_ATTR_RE = re.compile(r"^prt_t\d\d$")


def attribute_name(k):
    return f"{PREFIX}{k:02d}"


def attribute_count(order):
    return (order * order + 3) // 4


def is_transfer_attribute(name):
    return bool(_ATTR_RE.match(name))


# --- reading -------------------------------------------------------------------------------


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


def read_triangles(mesh, positions=None):
    """(T, 3) int32 vertex indices of the mesh's loop triangles, in Blender's order.

    Meshes of triangles and quads are triangulated here as Blender does it, about twice as fast
    as reading mesh.loop_triangles, whose foreach_get goes element by element (5.7 -> 2.9 ms for
    a 31k-quad mesh); meshes with n-gons read loop_triangles. positions: the mesh's vertex
    positions if already read.
    """
    corner_verts = read_corner_verts(mesh)
    starts = read_face_starts(mesh)
    sizes = np.diff(starts, append=np.int32(len(corner_verts)))
    if len(starts) == 0 or not ((sizes == 3) | (sizes == 4)).all():
        mesh.calc_loop_triangles()
        out = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
        if len(out):
            mesh.loop_triangles.foreach_get("vertices", out)
        return out.reshape(-1, 3)
    positions = read_positions(mesh) if positions is None else positions
    return triangulate_quads(corner_verts, starts, sizes, positions)


def triangulate_quads(corner_verts, starts, sizes, positions):
    """Vertex triangles of faces of 3 or 4 corners, as Blender's mesh tessellation
    (blenkernel mesh_tessellate.cc): a triangle is (0, 1, 2); a quad is (0, 1, 2), (0, 2, 3),
    or (0, 1, 3), (1, 2, 3) when the first split folds over (blenlib's
    is_quad_flip_v3_first_third_fast: (v2 - v1) x (v3 - v1) . (v4 - v1) x (v3 - v1) > 0,
    computed in float32 in the same order). A build of Blender that fuses multiply-adds (possible
    on arm64) can decide a quad whose test is within rounding of 0 the other way: either split
    covers that nearly flat quad."""
    per_face = sizes - 2
    first = np.cumsum(per_face) - per_face  # each face's first triangle
    corners = np.empty((int(per_face.sum()), 3), dtype=np.int32)
    tri = sizes == 3
    corners[first[tri]] = starts[tri, None] + np.int32([0, 1, 2])
    quad = ~tri
    if quad.any():
        quad_start, quad_first = starts[quad], first[quad]
        # Coordinates column by column (contiguous gathers; 12-byte rows gather element-wise).
        columns = np.ascontiguousarray(np.asarray(positions, dtype=np.float32).T)
        v = [[c[corner_verts[quad_start + i]] for c in columns] for i in range(4)]
        d12, d13, d14 = ([a - b for a, b in zip(v[i], v[0])] for i in (1, 2, 3))

        def cross(a, b):
            return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])

        with np.errstate(invalid="ignore", over="ignore"):  # non-finite positions: no flip
            ca, cb = cross(d12, d13), cross(d14, d13)
            flip = ((ca[0] * cb[0] + ca[1] * cb[1] + ca[2] * cb[2]) > np.float32(0.0)).view(np.int8)
        pair = np.empty((len(quad_start), 2, 3), dtype=np.int32)
        pair[:] = quad_start[:, None, None]
        pair += np.int32([[0, 1, 2], [0, 2, 3]])
        pair[:, 0, 2] += flip  # (0, 1, 3)
        pair[:, 1, 0] += flip  # (1, 2, 3)
        if len(quad_start) == len(starts):  # quads only: the pairs are the triangles in order
            corners = pair.reshape(-1, 3)
        else:
            corners[quad_first] = pair[:, 0]
            corners[quad_first + 1] = pair[:, 1]
    return corner_verts[corners]


def matrix_to_numpy(matrix):
    return np.array([list(row) for row in matrix], dtype=np.float64)


def transform_points(matrix4, points):
    m = np.asarray(matrix4, dtype=np.float64)
    return matmul_serial(np.asarray(points, dtype=np.float64), m[:3, :3].T) + m[:3, 3]


def transform_normals(matrix4, normals):
    """Normals under the inverse transpose of the linear part, renormalised (0 stays 0)."""
    linear = np.asarray(matrix4, dtype=np.float64)[:3, :3]
    # inv(linear)^T = cofactor matrix / det (rows: cross products of the rows); the normals are
    # renormalised, so only det's sign matters. Not np.linalg.inv, whose LAPACK call leaves an
    # OpenBLAS thread spinning (core.serial_blas).
    cofactor = np.cross(linear[[1, 2, 0]], linear[[2, 0, 1]])
    det = float(np.dot(linear[0], cofactor[0]))
    normal_matrix = cofactor * np.sign(det) if det != 0.0 and np.isfinite(det) else linear
    n = matmul_serial(np.asarray(normals, dtype=np.float64), normal_matrix.T)
    length = np.sqrt(np.einsum("ij,ij->i", n, n))[:, None]
    return np.divide(n, length, out=np.zeros_like(n), where=length > 1e-30)


def topology_fingerprint(mesh):
    """'V:E:F:L:hash' of the vertex, edge, face and corner counts and the corner/face layout."""
    h = hashlib.blake2b(digest_size=8)
    h.update(read_corner_verts(mesh).tobytes())
    h.update(read_face_starts(mesh).tobytes())
    return (
        f"{len(mesh.vertices)}:{len(mesh.edges)}:{len(mesh.polygons)}:{len(mesh.loops)}:"
        f"{h.hexdigest()}"
    )


@dataclass
class BakePoints:
    """Where the transfer is evaluated: P unique (position, normal) pairs in world space.

    `scatter` maps each element of the attribute domain (vertex or corner) to its point; for the
    POINT domain it is None (points are the vertices, in order).
    """

    domain: str
    positions: np.ndarray  # (P, 3) float64 world
    normals: np.ndarray  # (P, 3) float64 world, unit (or 0)
    scatter: object  # None or (E,) int64


def _vertex_points(matrix4, positions, normals):
    """POINT-domain BakePoints: one point per vertex, in order."""
    return BakePoints(
        "POINT", transform_points(matrix4, positions), transform_normals(matrix4, normals), None
    )


# Corner normals of one vertex that differ by at most this much in every component count as
# one normal: a flat grid's faces get normals of (0, 0, 1) and (0, 0, 0.99999994) from rounding,
# which would otherwise split its vertices into corners. The transfer changes by ~1e-6.
NORMAL_TOLERANCE = 1e-6


def vertex_normal_pairs(corner_verts, corner_normals, vertex_count):
    """The unique (vertex, normal) pairs of a mesh's corners: (vertex index, normal, inverse),
    sorted by vertex, with inverse mapping each corner to its pair. Corner normals within
    NORMAL_TOLERANCE of their vertex's reference normal (one of its corners') are that normal."""
    corner_normals = np.asarray(corner_normals, dtype=np.float32).reshape(-1, 3)
    reference = np.zeros((vertex_count, 3), dtype=np.float32)
    reference[corner_verts] = corner_normals  # one of the vertex's corners (the last written)
    at_reference = reference[corner_verts]
    close = np.ones(len(corner_verts), dtype=bool)
    for axis in range(3):  # (column by column: faster than a reduction along axis 1)
        close &= np.abs(corner_normals[:, axis] - at_reference[:, axis]) <= NORMAL_TOLERANCE
    if close.all():
        has_corner = np.zeros(vertex_count, dtype=bool)
        has_corner[corner_verts] = True
        vert = np.flatnonzero(has_corner)
        position = np.cumsum(has_corner) - 1
        return vert, reference[vert], position[corner_verts]
    snapped = np.where(close[:, None], at_reference, corner_normals)
    bits = np.ascontiguousarray(snapped).view(np.int32)
    # np.unique(rows, axis=0, return_inverse=True), computed with a lexsort of the int32 columns
    # (same order, same result; np.unique sorts the rows as structured items, ~5 times slower).
    order = np.lexsort((bits[:, 2], bits[:, 1], bits[:, 0], corner_verts))
    ordered_vert, ordered_bits = corner_verts[order], bits[order]
    new = np.empty(len(order), dtype=bool)
    new[:1] = True
    new[1:] = ordered_vert[1:] != ordered_vert[:-1]
    for axis in range(3):
        new[1:] |= ordered_bits[1:, axis] != ordered_bits[:-1, axis]
    inverse = np.empty(len(order), dtype=np.intp)
    inverse[order] = np.cumsum(new) - 1
    return ordered_vert[new], ordered_bits[new].view(np.float32), inverse


def bake_points(mesh, matrix4, positions=None):
    """BakePoints of an (evaluated) mesh whose topology matches the mesh being written.

    Domain: POINT when every vertex has a single normal over all its corners (mesh.normals_domain
    is POINT: all faces smooth, no sharp edges, no custom normals; or e.g. a flat plane, whose
    corners at a vertex all share the face normal up to NORMAL_TOLERANCE), else CORNER.
    positions: the mesh's local vertex positions if already read (read_positions).
    """
    positions = read_positions(mesh) if positions is None else positions
    if mesh.normals_domain == "POINT":
        return _vertex_points(matrix4, positions, read_vertex_normals(mesh))
    # Corners that share a vertex and a normal (smooth regions) get the same transfer: bake once.
    vert, normals, inverse = vertex_normal_pairs(
        read_corner_verts(mesh), read_corner_normals(mesh), len(positions)
    )
    if np.array_equal(vert, np.arange(len(positions))):  # sorted: exactly one normal each
        return _vertex_points(matrix4, positions, normals)
    return BakePoints(
        "CORNER",
        transform_points(matrix4, positions[vert]),
        transform_normals(matrix4, normals),
        inverse.astype(np.int64),
    )


# --- writing -------------------------------------------------------------------------------


def transfer_attribute_names(mesh):
    return sorted(a.name for a in mesh.attributes if is_transfer_attribute(a.name))


def snapshot(mesh):
    """Everything a bake may change on `mesh`, to restore it byte for byte."""
    attrs = []
    for name in transfer_attribute_names(mesh):
        attr = mesh.attributes[name]
        domain, data_type = attr.domain, attr.data_type
        size = len(attr.data)
        if data_type in ("FLOAT_COLOR", "BYTE_COLOR"):
            prop, width, dtype = "color", 4, np.float32
        elif data_type in ("FLOAT_VECTOR",):
            prop, width, dtype = "vector", 3, np.float32
        elif data_type == "FLOAT2":
            prop, width, dtype = "vector", 2, np.float32
        elif data_type == "INT":
            prop, width, dtype = "value", 1, np.int32
        elif data_type == "BOOLEAN":
            prop, width, dtype = "value", 1, bool
        else:
            prop, width, dtype = "value", 1, np.float32
        buf = np.empty(size * width, dtype=dtype)
        try:
            mesh.attributes[name].data.foreach_get(prop, buf)
        except (TypeError, AttributeError, RuntimeError) as error:
            raise ValueError(
                f"cannot read attribute '{name}' of mesh '{mesh.name}' to keep a copy, so the bake "
                f"would not be undoable on failure: {error}"
            ) from None
        attrs.append((name, domain, data_type, prop, buf))
    record = mesh.get(RECORD)
    record = record.to_dict() if hasattr(record, "to_dict") else record
    colors = mesh.color_attributes
    return {
        "attrs": attrs,
        "record": record,
        "active_color": colors.active_color_name,
        "default_color": colors.default_color_name,
    }


def _set_color_names(mesh, active, default):
    colors = mesh.color_attributes
    names = {a.name for a in colors}
    if active in names and colors.active_color_name != active:
        colors.active_color_name = active
    if default in names and colors.default_color_name != default:
        colors.default_color_name = default


def _remove(mesh, name):
    attr = mesh.attributes.get(name)
    if attr is not None:
        mesh.attributes.remove(attr)


def restore(mesh, snap):
    for name in transfer_attribute_names(mesh):
        _remove(mesh, name)
    for name, domain, data_type, prop, buf in snap["attrs"]:
        mesh.attributes.new(name, data_type, domain)
        mesh.attributes[name].data.foreach_set(prop, buf)
    if snap["record"] is None:
        if RECORD in mesh:
            del mesh[RECORD]
    else:
        mesh[RECORD] = snap["record"]
    _set_color_names(mesh, snap["active_color"], snap["default_color"])
    mesh.update()


def write_transfer(mesh, values, domain, record):
    """Write (E, n*n) float32 coefficients as prt_tKK attributes and the record on one mesh."""
    values = np.asarray(values, dtype=np.float32)
    count = (values.shape[1] + 3) // 4
    packed = np.zeros((values.shape[0], count * 4), dtype=np.float32)
    packed[:, : values.shape[1]] = values
    colors = mesh.color_attributes
    active, default = colors.active_color_name, colors.default_color_name
    for k in range(count):
        name = attribute_name(k)
        old = mesh.attributes.get(name)
        if old is not None and (old.domain != domain or old.data_type != "FLOAT_COLOR"):
            _remove(mesh, name)
        if mesh.attributes.get(name) is None:
            mesh.color_attributes.new(name, "FLOAT_COLOR", domain)
        channel = np.ascontiguousarray(packed[:, 4 * k : 4 * k + 4]).reshape(-1)
        mesh.attributes[name].data.foreach_set("color", channel)
    for name in transfer_attribute_names(mesh):
        if int(name[len(PREFIX):]) >= count:
            _remove(mesh, name)
    mesh[RECORD] = dict(record, count=count, domain=domain)
    _set_color_names(mesh, active, default)
    mesh.update()


def write_bakes(items):
    """items: [(mesh, values, domain, record)]. All are written, or none (state restored)."""
    snapshots = [(mesh, snapshot(mesh)) for mesh, _v, _d, _r in items]
    try:
        for mesh, values, domain, record in items:
            write_transfer(mesh, values, domain, record)
    except BaseException:
        for mesh, snap in snapshots:
            restore(mesh, snap)
        raise


@dataclass
class BakeRecord:
    """The parsed mesh["prt_bake"] of a bake whose attributes are all present (docs/storage.md)."""

    order: int
    count: int
    domain: str
    record: object  # the IDProperty group itself


def read_bake_record(mesh):
    """(BakeRecord, "") when the mesh holds a complete bake (stale or not: the topology is not
    checked here), else (None, why not)."""
    record = mesh.get(RECORD) if mesh is not None else None
    if record is None:
        return None, "not baked"
    try:
        order, count, domain = int(record["order"]), int(record["count"]), str(record["domain"])
    except (KeyError, TypeError, ValueError):
        return None, "the bake record is incomplete"
    if order < 1 or count != attribute_count(order) or domain not in ("POINT", "CORNER"):
        return None, "the bake record is inconsistent"
    for k in range(count):
        attr = mesh.attributes.get(attribute_name(k))
        if attr is None or attr.domain != domain or attr.data_type != "FLOAT_COLOR":
            return None, f"attribute {attribute_name(k)} is missing or changed"
    return BakeRecord(order, count, domain, record), ""


def read_transfer(mesh, bake=None, padded=False):
    """(E, n*n) float32 coefficients of the last bake, or None when there is none usable.
    bake: its BakeRecord if already read; padded: keep the 4 * count channels (zero padding)."""
    if bake is None:
        bake, _problem = read_bake_record(mesh)
        if bake is None:
            return None
    names = [attribute_name(k) for k in range(bake.count)]
    size = len(mesh.attributes[names[0]].data)
    packed = np.empty((bake.count, size * 4), dtype=np.float32)
    for k, name in enumerate(names):
        mesh.attributes[name].data.foreach_get("color", packed[k])
    values = packed.reshape(bake.count, size, 4).transpose(1, 0, 2).reshape(size, bake.count * 4)
    return np.ascontiguousarray(values if padded else values[:, : bake.order * bake.order])


# --- status --------------------------------------------------------------------------------

_fingerprint_cache = {}


def cached_fingerprint(mesh):
    """topology_fingerprint, cached for big meshes by (pointer, counts) (for UI drawing)."""
    key = (mesh.as_pointer(), len(mesh.vertices), len(mesh.edges), len(mesh.polygons), len(mesh.loops))
    if key[-1] < 200_000:
        return topology_fingerprint(mesh)
    value = _fingerprint_cache.get(key)
    if value is None:
        if len(_fingerprint_cache) > 64:
            _fingerprint_cache.clear()
        value = _fingerprint_cache[key] = topology_fingerprint(mesh)
    return value


def forget_cached_fingerprints(mesh):
    """Drop the cached fingerprints of `mesh` (its geometry changed, perhaps not its counts)."""
    pointer = mesh.as_pointer()
    for key in [k for k in _fingerprint_cache if k[0] == pointer]:
        del _fingerprint_cache[key]


def stale_topology(mesh, record, use_cache=False, allow_missing=False):
    """Why the fingerprint stored in the bake record does not match the mesh's topology, or ""
    when it does. A record without a fingerprint is incomplete, or accepted with allow_missing.
    use_cache: compare with cached_fingerprint (UI drawing) instead of the exact fingerprint."""
    stored = record.get("fingerprint")
    if stored is None:
        return "" if allow_missing else "the bake record is incomplete"
    current = cached_fingerprint(mesh) if use_cache else topology_fingerprint(mesh)
    return "" if current == str(stored) else "the topology changed since the bake"


def bake_status(mesh, use_cache=False):
    """('NONE' | 'FRESH' | 'STALE', reason) of the transfer stored on `mesh`."""
    if mesh is None:
        return "NONE", "not a mesh"
    if mesh.get(RECORD) is None:
        return "NONE", "not baked"
    if getattr(mesh, "is_editmode", False):
        return "STALE", "in Edit Mode: leave Edit Mode to check the bake"
    bake, problem = read_bake_record(mesh)
    if bake is None:
        return "STALE", f"{problem}: bake again"
    problem = stale_topology(mesh, bake.record, use_cache=use_cache)
    if problem:
        return "STALE", f"{problem}: bake again"
    return "FRESH", f"order {bake.order}, {bake.domain.lower()} domain"
