"""The scene's occluding triangles: every visible mesh instance in world space, and the ray
origin offset and self-occlusion of a mesh, as the bake and the lights' shading both trace them."""

from dataclasses import dataclass

import numpy as np

from ...core.trace import raytrace
from ...core.transfer.mesh import matrix_to_numpy, transform_points
from . import mesh_read

# Ray origin offset along the normal: OFFSET_REL times the world bounding-box diagonal of the
# object being baked, and at least OFFSET_ULP times its largest coordinate (float32 rounding).
OFFSET_REL = 1e-4
OFFSET_ULP = 1e-5


@dataclass
class PartSource:
    """Where a scene part's triangles came from: the evaluated object and mesh, its world matrix,
    its local positions, and the indices of the triangles kept (None: all)."""

    obj: object
    mesh: object
    matrix: np.ndarray
    positions: np.ndarray
    kept: object = None


def scene_parts(depsgraph, cache=None, sources=None):
    """World-space triangles of every visible mesh instance: [(original object or None, V, T)].
    cache: {evaluated mesh pointer: (positions, triangles)} already read (filled in here);
    sources: a list to receive, per part, PartSource (what interreflected bakes read next)."""
    cache = {} if cache is None else cache
    parts = []
    for inst in depsgraph.object_instances:
        ob = inst.object
        if ob.type != "MESH":
            continue
        mesh = ob.data
        key = mesh.as_pointer()
        if key not in cache:
            positions = mesh_read.read_positions(mesh)
            cache[key] = (positions, mesh_read.read_triangles(mesh, positions))
        positions, triangles = cache[key]
        if len(triangles) == 0:
            continue
        owner = None if inst.is_instance else ob.original
        with np.errstate(invalid="ignore", over="ignore"):  # NaN/Inf vertices: dropped below
            world = transform_points(matrix_to_numpy(inst.matrix_world), positions)
            world = world.astype(np.float32)
        kept = None
        if not np.isfinite(world).all():  # NaN/Inf vertices cannot occlude: drop their triangles
            finite = np.isfinite(world).all(axis=1)
            world = np.where(finite[:, None], world, np.float32(0.0))
            kept = np.flatnonzero(finite[triangles].all(axis=1))
            triangles = triangles[kept]
            if len(triangles) == 0:
                continue
        parts.append((owner, world, triangles))
        if sources is not None:
            sources.append(PartSource(ob, mesh, matrix_to_numpy(inst.matrix_world), positions, kept))
    return parts


def ray_setup(world, triangles, mesh, cull, diagonal=None):
    """(ray origin offset, whether rays may hit the mesh itself) for a mesh at world positions:
    the offset is OFFSET_REL of its bounding-box diagonal, at least OFFSET_ULP of its largest
    coordinate (docs/bake.md, "Ray origins"); with culling, a planar or closed convex mesh
    without custom normals cannot occlude itself."""
    if diagonal is None:
        lower, upper = raytrace.bounding_box(world)
        diagonal = float(np.linalg.norm(upper - lower))
    offset = max(OFFSET_REL * diagonal, OFFSET_ULP * float(np.abs(world).max()), 1e-30)
    self_occludes = True
    if cull and not mesh.has_custom_normals:
        self_occludes = not raytrace.cannot_self_occlude(world, triangles)
    return offset, self_occludes
