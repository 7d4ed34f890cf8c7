"""The plan of each object to bake, or the reason it cannot be baked."""

from dataclasses import dataclass

import bpy
import numpy as np

from ...core.sh import frames
from ...core.trace import raytrace
from ...core.transfer import back as back_side
from ...core.transfer.mesh import matrix_to_numpy, transform_points
from ..scene import mesh_read, storage
from ..scene.parts import ray_setup
from .texels import texel_computation, texel_image

# Objects that hold no geometry to bake (selected with the meshes, they are left out quietly).
NO_GEOMETRY = {"CAMERA", "LIGHT", "EMPTY", "LIGHT_PROBE", "SPEAKER", "ARMATURE", "LATTICE"}


@dataclass
class _Plan:
    obj: object
    name: str
    mesh: object
    matrix: np.ndarray
    points: object  # mesh_read.BakePoints (None until prepared)
    fingerprint: str
    offset: float
    self_occludes: bool
    own_vertices: np.ndarray  # world-space float32 triangles of the evaluated object
    own_triangles: np.ndarray
    computation: object = None
    occluder: object = None
    boxes: object = None  # (K, 2, 3) boxes of the other occluders, or None (no culling)
    source: object = None  # (evaluated mesh, its local positions) until the points are read
    texels: object = None  # texels.TexelGeometry of a texel bake
    back: object = None  # the back side's computation of an open mesh
    image: object = None  # a texel bake's transfer image (object frame), made as its tracing ends

    def computations(self):
        """The plan's computations: its transfer's, then its back side's if it has one."""
        return [c for c in (self.computation, self.back) if c is not None]


def back_computation(job, plan):
    """The computation of the back side of an open mesh, or None: the same points (texel
    samples) and directions for the flipped normals, the origins offset to the back and moved
    into the faces turned over where surfaces touch (a texel bake: its back normals, zero where
    the back lies under another surface); no hits, so direct light only (docs/bake.md, "Back faces")."""
    if plan.texels is not None:
        normals = plan.texels.back_normals
        if normals is None:
            return None
        return texel_computation(plan, job.directions, job.settings, job._pool, normals=normals)
    if not back_side.is_open(plan.own_triangles):
        return None
    surface = None
    if plan.occluder is not None:
        surface = (plan.own_vertices, back_side.turned_over_triangles(plan.own_triangles))
    points = back_side.turned_over(plan.points)
    return job.transfer_computation(points, plan.occluder, plan.offset, plan.self_occludes, plan.boxes, surface)


def back_values(plan):
    """The back transfer in the object's local frame per element (a texel bake: its image, as
    the front's), or None (no back side)."""
    if plan.back is None:
        return None
    local = frames.to_local_frame(plan.back.coeffs, plan.matrix[:3, :3])
    if plan.texels is not None:
        return texel_image(plan.texels.samples, local, plan.texels.seams)
    return local if plan.points.scatter is None else local[plan.points.scatter]


def bake_record(settings, plan, backend, stats, result):
    """The record of one plan's bake (docs/storage.md; write_bakes adds its layout)."""
    s = settings
    return {
        "version": storage.FORMAT_VERSION,
        "order": s.order,
        "samples": s.samples,
        "direction_set": s.direction_set,
        "seed": int(s.seed),
        "shadows": bool(s.shadows),
        "self_shadow_only": bool(s.self_shadow_only),
        "backend": backend,
        "fingerprint": plan.fingerprint,
        "offset": float(plan.offset),
        "seconds": float(stats.seconds),
        "rays_traced": int(stats.rays_traced),
        "rays_skipped": int(stats.rays_skipped),
        "error_estimate": result.error_rms(),
        "error_estimate_relative": result.error_relative(),
        "bounces": int(s.bounces),
    }


def _modifier_names(obj):
    return ", ".join(f"{m.name} ({m.type.replace('_', ' ').title()})" for m in obj.modifiers if m.show_viewport)


def check_object(obj, depsgraph, seen_meshes, reads, cull):
    """The bake plan of `obj`, or a string saying why it cannot be baked. seen_meshes: mesh
    name -> object name of the plans so far; reads: evaluated mesh pointer -> (positions,
    triangles) already read; cull: whether rays where nothing can occlude may be skipped."""
    if not isinstance(obj, bpy.types.Object):
        return f"is not an object ({type(obj).__name__})"
    name = obj.name
    if obj.type != "MESH":
        return f"is a {obj.type.lower()}, not a mesh: convert it (Object > Convert > Mesh) to bake it"
    mesh = obj.data
    if obj.mode == "EDIT" or mesh.is_editmode:
        return "is in Edit Mode: switch to Object Mode, then bake"
    if obj.library is not None or mesh.library is not None:
        return (
            "is linked from a library and cannot be written: make it local "
            "(Object > Relations > Make Local > Selected Objects and Data) to bake it"
        )
    if len(mesh.polygons) == 0:
        return "has no faces: a transfer bake needs faces (it only has vertices/edges)"
    if mesh.name in seen_meshes:
        return (
            f"shares its mesh '{mesh.name}' with '{seen_meshes[mesh.name]}': make it single "
            "user (Object > Relations > Make Single User > Object & Data) to bake both"
        )
    obj_eval = obj.evaluated_get(depsgraph)
    mesh_eval = obj_eval.data
    fingerprint = mesh_read.topology_fingerprint(mesh)
    modified = any(m.show_viewport for m in obj.modifiers)
    if modified and mesh_read.topology_fingerprint(mesh_eval) != fingerprint:
        return (
            f"has modifiers that change its topology [{_modifier_names(obj)}]: apply them "
            "(Object > Apply > Visual Geometry to Mesh) or turn them off in the viewport, "
            "then bake again"
        )
    matrix = matrix_to_numpy(obj_eval.matrix_world)
    if not np.isfinite(matrix).all():
        return "has a non-finite transform (NaN or infinity in location, rotation or scale)"
    cached = reads.get(mesh_eval.as_pointer())
    positions = cached[0] if cached else mesh_read.read_positions(mesh_eval)
    if not np.isfinite(positions).all():
        bad = int(np.count_nonzero(~np.isfinite(positions).all(axis=1)))
        return (
            f"has {bad} vertices with non-finite coordinates (NaN or infinity): fix or delete "
            "them (e.g. in Edit Mode, Mesh > Clean Up), then bake again"
        )
    world = transform_points(matrix, positions)
    lower, upper = raytrace.bounding_box(world)
    diagonal = float(np.linalg.norm(upper - lower))
    if not diagonal > 0.0 or abs(np.linalg.det(matrix[:3, :3])) < 1e-30:
        return "has zero size (all its vertices are at one point, or a scale of 0): its faces have no area to bake"
    seen_meshes[mesh.name] = name
    triangles = cached[1] if cached else mesh_read.read_triangles(mesh_eval, positions)
    offset, self_occludes = ray_setup(world, triangles, mesh_eval, cull, diagonal)
    return _Plan(
        obj,
        name,
        mesh,
        matrix,
        None,
        fingerprint,
        offset,
        self_occludes,
        world.astype(np.float32),
        triangles,
        source=(mesh_eval, positions),
    )
