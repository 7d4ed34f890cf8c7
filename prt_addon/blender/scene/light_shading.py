"""The split lights' part of `lighting.shade`: power / pi * max(0, n . s) * V per element, with V
traced against the scene's occluders as the bake builds them."""

import hashlib

import numpy as np

from ...core.lights import visibility as light_visibility
from ...core.transfer.back import turned_over, turned_over_triangles
from ...core.transfer.contact import inward_tangents
from ...core.transfer.mesh import concatenate_parts, matrix_to_numpy, transform_points, vertex_points
from .. import caches
from . import mesh_read
from .occluders import BUILDERS, auto_backend
from .parts import OFFSET_REL, OFFSET_ULP, scene_parts

RAYS_PER_LIGHT = 16  # rays over each light's disc per element (core.lights.visibility.disc_directions)

_occluders = {}  # "scene" or "self" -> (key of the triangles, occluder); one of each is kept


def _occluder(kind, vertices, triangles):
    """The occluder of these world-space triangles, built once per distinct geometry."""
    digest = hashlib.blake2b(digest_size=16)
    digest.update(np.ascontiguousarray(vertices, dtype=np.float32).tobytes())
    digest.update(np.ascontiguousarray(triangles, dtype=np.int32).tobytes())
    backend = auto_backend()
    key = (backend, digest.hexdigest())
    cached = _occluders.get(kind)
    if cached is not None and cached[0] == key:
        return cached[1]
    occluder = BUILDERS[backend](
        np.ascontiguousarray(vertices, dtype=np.float32), np.ascontiguousarray(triangles, dtype=np.int32)
    )
    _occluders[kind] = (key, occluder)
    return occluder


@caches.on_clear
def clear_cache():
    _occluders.clear()


def element_points(obj_eval, domain, side="FRONT"):
    """(world points, world unit normals, offset, tangents) per element of the stored bake's
    domain: one row per vertex (POINT) or per face corner (CORNER), read as the bake reads them;
    tangents are the bake's contact tangents (core.transfer.contact.inward_tangents), which move
    the ray origins into the element's own surface where another surface touches it. side
    "BACK": the normals flipped and the tangents of the faces turned over (the back side's bake)."""
    mesh = obj_eval.data
    matrix = matrix_to_numpy(obj_eval.matrix_world)
    positions = mesh_read.read_positions(mesh)
    points = mesh_read.bake_points(mesh, matrix, positions)
    if domain != "CORNER" and points.scatter is not None:  # the normals split since the bake
        points = vertex_points(matrix, positions, mesh_read.read_vertex_normals(mesh))
    world = transform_points(matrix, positions)
    triangles = mesh_read.read_triangles(mesh, positions)
    if side == "BACK":
        points, triangles = turned_over(points), turned_over_triangles(triangles)
    tangents = inward_tangents(points.positions, points.normals, world, triangles, points.vertex)
    if domain == "CORNER":
        rows = mesh_read.read_corner_verts(mesh) if points.scatter is None else points.scatter
        world_points, normals, tangents = points.positions[rows], points.normals[rows], tangents[rows]
    else:
        world_points, normals = points.positions, points.normals
    diagonal = float(np.linalg.norm(world.max(axis=0) - world.min(axis=0))) if len(world) else 0.0
    biggest = float(np.abs(world).max()) if len(world) else 0.0
    offset = max(OFFSET_REL * diagonal, OFFSET_ULP * biggest, 1e-30)
    return np.asarray(world_points, np.float64), np.asarray(normals, np.float64), offset, tangents


def scene_occluder(depsgraph, obj_eval=None):
    """The occluder of every visible mesh (parts.scene_parts), or of obj_eval alone."""
    if obj_eval is None:
        vertices, triangles = concatenate_parts(scene_parts(depsgraph))
        kind = "scene"
    else:
        mesh = obj_eval.data
        positions = mesh_read.read_positions(mesh)
        triangles = mesh_read.read_triangles(mesh, positions)
        vertices = transform_points(matrix_to_numpy(obj_eval.matrix_world), positions).astype(np.float32)
        kind = "self"
    return None if len(triangles) == 0 else _occluder(kind, vertices, triangles)


def light_radiance(obj, depsgraph, lights, info, rays_per_light=RAYS_PER_LIGHT, side="FRONT"):
    """(elements, 3) radiance of the lights on obj's `side`, white albedo, shadowed as its bake was:
    by every visible mesh, by the object alone (self-shadow only), or not at all (shadows off)."""
    obj_eval = obj.evaluated_get(depsgraph)
    points, normals, offset, tangents = element_points(obj_eval, info.domain, side)
    if not lights:
        return np.zeros((len(points), 3))
    record = getattr(info, "record", None)
    shadows = bool(record.get("shadows", True)) if record is not None else True
    self_only = bool(record.get("self_shadow_only", False)) if record is not None else False
    visibility = None
    if shadows:
        occluder = scene_occluder(depsgraph, obj_eval if self_only else None)
        if occluder is not None:
            visibility = light_visibility.light_visibility(
                points, normals, lights, occluder, rays_per_light=rays_per_light, offset=offset, tangents=tangents
            )
    return light_visibility.light_irradiance(normals, lights, visibility)
