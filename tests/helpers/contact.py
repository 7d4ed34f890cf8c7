"""Contact scenes: the shared direction set, meshes merged, Embree when there, a unit world's radiance (numpy); walls, grids and their bake in Blender (bpy passed in)."""

import numpy as np
import pytest

from prt_addon.core.sh import directions
from prt_addon.core.trace import raytrace
from prt_addon.core.transfer import quadrature as transfer

DIRECTIONS = 1024  # PRT


embree = pytest.mark.skipif(not raytrace.EMBREE_AVAILABLE, reason="embreex not installed")


def merged(*meshes):
    verts, tris, base = [], [], 0
    for v, t in meshes:
        verts.append(v)
        tris.append(t + base)
        base += len(v)
    return np.concatenate(verts), np.concatenate(tris)


def unit_world_radiance(result):
    """E/pi under a uniform world of radiance 1: sqrt(4 pi) t_0."""
    return np.sqrt(4.0 * np.pi) * result.coeffs[:, 0].astype(np.float64)


def _add(bpy, scene, name, build, location=(0.0, 0.0, 0.0)):
    import bmesh

    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    build(bmesh, bm)
    bm.to_mesh(mesh)
    bm.free()
    mesh.materials.append(bpy.data.materials.new(name))
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    scene.collection.objects.link(obj)
    return obj


def _grid(size, cuts):
    return lambda bmesh, bm: bmesh.ops.create_grid(bm, x_segments=cuts, y_segments=cuts, size=size / 2)


def _wall(width, height, cuts):
    def build(bmesh, bm):
        bmesh.ops.create_grid(bm, x_segments=cuts, y_segments=cuts, size=0.5)
        for v in bm.verts:  # the grid's (x, y) in [-1/2, 1/2] -> (0, x w, (y + 1/2) h): faces +x
            x, y, _z = v.co
            v.co = (0.0, x * width, (y + 0.5) * height)

    return build


def _read(obj):
    """World vertices (V, 3), loop triangles (T, 3), corner vertices (L,), corner normals."""
    mesh = obj.data
    world = np.array(obj.matrix_world)
    v = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", v)
    v = v.reshape(-1, 3).astype(np.float64) @ world[:3, :3].T + world[:3, 3]
    mesh.calc_loop_triangles()
    t = np.empty(len(mesh.loop_triangles) * 3, np.int32)
    mesh.loop_triangles.foreach_get("vertices", t)
    corner_verts = np.empty(len(mesh.loops), np.int32)
    mesh.loops.foreach_get("vertex_index", corner_verts)
    n = np.empty(len(mesh.loops) * 3, np.float32)
    mesh.corner_normals.foreach_get("vector", n)
    n = n.reshape(-1, 3).astype(np.float64) @ np.linalg.inv(world[:3, :3])
    return v, t.reshape(-1, 3), corner_verts, n


def _prt(objs, target, occluder_kind="EMBREE"):
    """E/pi per corner of objs[target] with every object an occluder: (new, old, v, n)."""
    parts = [_read(o) for o in objs]
    verts, tris = merged(*[(p[0], p[1]) for p in parts])
    if occluder_kind == "EMBREE":
        occluder = raytrace.EmbreeOccluder(verts, tris)
    else:
        from prt_addon.blender.scene.occluders import BVHTreeOccluder

        occluder = BVHTreeOccluder(verts, tris)
    v, t, corner_verts, n = parts[target]
    diagonal = np.linalg.norm(v.max(axis=0) - v.min(axis=0))
    offset = max(1e-4 * diagonal, 1e-5 * np.abs(v).max())  # as the bake job's
    dirs = directions.make_directions("FIBONACCI", DIRECTIONS, 0)
    out = []
    for extra in ({"surface": (v, t), "point_vertex": corner_verts}, {}):
        result = transfer.TransferComputation(v[corner_verts], n, dirs, 1, occluder, offset=offset, **extra).run()
        out.append(unit_world_radiance(result))
    return out[0], out[1], v[corner_verts], n
