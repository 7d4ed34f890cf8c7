"""Contact scenes under an HDRI with its lights split: a box on the ground, a wall on a floor, a room of single quads; E/pi per corner from PRT and Cycles (bpy passed in)."""

import numpy as np

from helpers.cycles import cycles_vertex_bake
from helpers.worlds import bundled_hdri_path, new_world, use_image

ORDER = 8
DIRECTIONS = 1024  # PRT
SAMPLES = 512  # Cycles
LUMA = np.array([0.2126, 0.7152, 0.0722])


def hdri_world(bpy, scene, name="courtyard"):
    world = new_world(bpy, scene)
    use_image(world, bpy.data.images.load(bundled_hdri_path(name)))
    return world


def white(bpy, objects):
    material = bpy.data.materials.new("white")
    for obj in objects:
        obj.data.materials.append(material)


def mesh_object(bpy, scene, name, build, location=(0.0, 0.0, 0.0)):
    import bmesh

    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    build(bmesh, bm)
    bm.to_mesh(mesh)
    bm.free()
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    scene.collection.objects.link(obj)
    return obj


def box(size, cuts):
    def build(bmesh, bm):
        bmesh.ops.create_cube(bm, size=size)
        bmesh.ops.subdivide_edges(bm, edges=bm.edges[:], cuts=cuts, use_grid_fill=True)

    return build


def grid(size, cuts):
    return lambda bmesh, bm: bmesh.ops.create_grid(bm, x_segments=cuts, y_segments=cuts, size=size / 2)


def quad(corners):
    """One quad face through four corners (its normal by their order, right-handed)."""

    def build(bmesh, bm):
        bm.faces.new([bm.verts.new(c) for c in corners])

    return build


def room_quads(s=2.0):
    """{name: corners} of a room of five single quads facing in: a floor, three walls and half a
    ceiling (open at the front and over the back half)."""
    return {
        "floor": [(-s, -s, 0), (s, -s, 0), (s, s, 0), (-s, s, 0)],
        "left": [(-s, -s, 0), (-s, s, 0), (-s, s, 2 * s), (-s, -s, 2 * s)],
        "right": [(s, -s, 0), (s, -s, 2 * s), (s, s, 2 * s), (s, s, 0)],
        "back": [(-s, s, 0), (s, s, 0), (s, s, 2 * s), (-s, s, 2 * s)],
        "ceiling": [(-s, -s, 2 * s), (-s, 0, 2 * s), (s, 0, 2 * s), (s, -s, 2 * s)],
    }


def cycles_corners(bpy, scene, objects, samples=SAMPLES):
    """{name: (corners, 3)} E/pi per corner from Cycles' DIFFUSE / DIRECT vertex-colour bake."""
    return cycles_vertex_bake(bpy, scene, objects, samples, domain="CORNER")


def shade_corners(api, obj, scene):
    """api.shade(obj) per corner (a POINT bake's vertices spread to their corners)."""
    values = np.asarray(api.shade(obj, scene), dtype=np.float64)
    mesh = obj.data
    if len(values) == len(mesh.loops):
        return values
    corner_verts = np.empty(len(mesh.loops), np.int32)
    mesh.loops.foreach_get("vertex_index", corner_verts)
    return values[corner_verts]


def corner_frame(obj):
    """(world positions, world normals) per corner of obj."""
    mesh = obj.data
    world = np.array(obj.matrix_world)
    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3).astype(np.float64) @ world[:3, :3].T + world[:3, 3]
    corner_verts = np.empty(len(mesh.loops), np.int32)
    mesh.loops.foreach_get("vertex_index", corner_verts)
    n = np.empty(len(mesh.loops) * 3, np.float32)
    mesh.corner_normals.foreach_get("vector", n)
    n = n.reshape(-1, 3).astype(np.float64) @ np.linalg.inv(world[:3, :3])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return co[corner_verts], n


def row_means(values, key, select):
    """{rounded key: mean luminance of the selected corners with that key}."""
    lum = values @ LUMA
    keys = np.round(key, 4)
    return {float(k): float(lum[select & (keys == k)].mean()) for k in np.unique(keys[select])}
