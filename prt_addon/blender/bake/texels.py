"""Texel bakes: each object's lightmap UV map (found, or unwrapped and kept aside), its resolution, its samples.

A bake never changes a mesh before it writes: a UV map the bake makes is unwrapped on a
temporary layer, read into numpy and removed again at once; finish() writes it back with the
transfer images, all or nothing (storage.write_bakes).
"""

from dataclasses import dataclass

import bpy
import numpy as np

from ...core.transfer import adaptive, back as back_side, contact, lightmap, split, texels
from ...core.transfer.mesh import concatenate_parts
from ..scene import mesh_read
from .settings import MAX_RESOLUTION, BakeError, memory_budget, texel_memory

LIGHTMAP_UV_NAME = "PRT Lightmap"  # the UV map a texel bake makes when the mesh has no lightmap UV map
DEFAULT_DENSITY = 20.0  # texels per metre of surface, when no resolution is given
MIN_RESOLUTION = 8
PACKING = 0.6  # the UV area Smart UV Project is expected to cover, for the first resolution guess


@dataclass
class TexelGeometry:
    """What a texel bake of one object needs of its mesh (world space), and the map it bakes into."""

    uv_name: str
    created_uvs: object  # (corners, 2) float32 UVs to write as a new UV map at finish(), or None
    resolution: int
    samples: object  # core.transfer.texels.TexelSamples (world space)
    seams: object  # core.transfer.lightmap.SeamPairs
    notes: list
    uvs: object = None  # (T, 3, 2) float64 UVs of the loop triangles (the texel nodes of bounces)
    back_normals: object = None  # (S, P, 3) the back side's sample normals of an open mesh, else None


def lightmap_uv_name(mesh, requested):
    """The UV map to bake into: `requested` when given (it must exist), else the first UV map whose
    name contains "lightmap" (any case), else None (the bake makes one). Raises BakeError."""
    names = mesh_read.uv_map_names(mesh)
    if requested:
        if requested not in names:
            have = ", ".join(f"'{n}'" for n in names) or "none"
            raise BakeError(f"has no UV map '{requested}' (its UV maps: {have}): pick one, or leave UV Map empty")
        return requested
    for name in names:
        if "lightmap" in name.lower():
            return name
    return None


def resolution_for(world_area, uv_area, density):
    """Texels per side so that a metre of surface gets `density` texels: res = density *
    sqrt(world area / UV area), rounded up to a multiple of 4 within [MIN, MAX]_RESOLUTION."""
    if not (world_area > 0 and uv_area > 0):
        return MIN_RESOLUTION
    res = int(np.ceil(density * np.sqrt(world_area / uv_area) / 4.0)) * 4
    return int(min(MAX_RESOLUTION, max(MIN_RESOLUTION, res)))


def _areas(positions, uvs):
    """(world area, UV area) of triangles given as (T, 3, 3) and (T, 3, 2)."""
    world = 0.5 * np.linalg.norm(np.cross(positions[:, 1] - positions[:, 0], positions[:, 2] - positions[:, 0]), axis=1)
    e1, e2 = uvs[:, 1] - uvs[:, 0], uvs[:, 2] - uvs[:, 0]
    uv = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    return float(world.sum()), float(uv.sum())


def unwrap(obj, margin):
    """(corners, 2) float32 UVs of a Smart UV Project of `obj` on a temporary UV map, which is
    removed again: the mesh, its UV maps, selection and mode are left as they were."""
    mesh = obj.data
    layers = mesh.uv_layers
    active, render = layers.active_index, next((i for i, uv in enumerate(layers) if uv.active_render), -1)
    select = {kind: np.empty(len(getattr(mesh, kind)), dtype=bool) for kind in ("vertices", "edges", "polygons")}
    hide = {kind: np.empty(len(getattr(mesh, kind)), dtype=bool) for kind in select}
    for kind in select:
        getattr(mesh, kind).foreach_get("select", select[kind])
        getattr(mesh, kind).foreach_get("hide", hide[kind])
    attributes_before = set(mesh.attributes.keys())
    temporary = layers.new(name="PRT unwrap")
    if temporary is None:
        raise BakeError("cannot add a UV map for the lightmap (a mesh holds at most 8): remove one, or name one")
    name = temporary.name
    try:
        layers.active = layers[name]
        view_layer = bpy.context.view_layer
        with bpy.context.temp_override(
            active_object=obj, object=obj, selected_objects=[obj], selected_editable_objects=[obj]
        ):
            previous = view_layer.objects.active
            view_layer.objects.active = obj
            try:
                bpy.ops.object.mode_set(mode="EDIT")
                if any(h.any() for h in hide.values()):
                    bpy.ops.mesh.reveal(select=False)
                bpy.ops.mesh.select_all(action="SELECT")
                bpy.ops.uv.smart_project(angle_limit=np.radians(66.0), island_margin=margin, area_weight=0.0)
                bpy.ops.object.mode_set(mode="OBJECT")
            finally:
                view_layer.objects.active = previous
        uvs = mesh_read.read_corner_uvs(mesh, name).copy()
    finally:
        if name in layers:
            layers.remove(layers[name])
        for kind in select:
            if hide[kind].any():
                getattr(mesh, kind).foreach_set("hide", hide[kind])
            getattr(mesh, kind).foreach_set("select", select[kind])
        for name in set(mesh.attributes.keys()) - attributes_before:  # (edit mode's .hide_*, .uv_select_*)
            if name.startswith(".") and name in mesh.attributes:
                mesh.attributes.remove(mesh.attributes[name])
        if 0 <= active < len(layers):
            layers.active_index = active
        if 0 <= render < len(layers):
            layers[render].active_render = True
        mesh.update()
    return uvs


def unwrap_ahead(objects, settings):
    """{object name: (corners, 2) UVs} of a Smart UV Project for every mesh object that a texel
    bake will need a lightmap UV map for and has none. Done before the bake reads the scene:
    the mode switches of the unwrap free the evaluated meshes read before them."""
    out = {}
    if settings.target == "VERTICES":
        return out
    for obj in objects:
        if getattr(obj, "type", None) != "MESH" or obj.mode == "EDIT" or len(obj.data.polygons) == 0:
            continue
        if obj.library is not None or obj.data.library is not None:
            continue
        try:
            if lightmap_uv_name(obj.data, settings.uv_map) is not None:
                continue
        except BakeError:
            continue  # (refused when its plan is made)
        mesh = obj.data
        world = mesh_read.world_triangles(mesh, np.array(obj.matrix_world))[2]
        area = _areas(world, np.zeros((len(world), 3, 2)))[0]
        if settings.target == "AUTO" and not len(mesh.vertices) < area * settings.texel_density**2 / 16.0:
            continue
        guess = settings.resolution or resolution_for(area, PACKING, settings.texel_density)
        out[obj.name] = unwrap(obj, margin=min(0.2, 2.0 * lightmap.GUTTER / guess))
    return out


def texel_geometry(plan, mesh_eval, positions, uv_map, resolution, density, unwrapped=None):
    """The TexelGeometry of a plan (bake.plans): the UV map, the resolution, the texel samples in
    world space with the plan's ray offset as their inset from the triangles' edges."""
    notes = []
    mesh = plan.mesh
    uv_name = lightmap_uv_name(mesh, uv_map)
    created = None
    corners, vertices, world, world_normals = mesh_read.world_triangles(mesh_eval, plan.matrix, positions)
    if uv_name is None:
        created = (unwrapped or {}).get(plan.name)
        if created is None:
            raise BakeError("has no lightmap UV map and none was made for it")
        uv_name = LIGHTMAP_UV_NAME
        corner_uvs = created
        notes.append(f"made the UV map '{uv_name}' (Smart UV Project)")
    elif uv_name in mesh_read.uv_map_names(mesh_eval):
        corner_uvs = mesh_read.read_corner_uvs(mesh_eval, uv_name)
    else:  # (a modifier dropped the map: the original's, same topology)
        corner_uvs = mesh_read.read_corner_uvs(mesh, uv_name)
    uvs = corner_uvs[corners].astype(np.float64)
    if resolution is None:
        world_area, uv_area = _areas(world, uvs)
        resolution = resolution_for(world_area, uv_area, density)
    samples = texels.texel_samples(uvs, world, world_normals, resolution, inset=plan.offset)
    if samples.degenerate == len(uvs):
        raise BakeError(f"UV map '{uv_name}' has no area (every face is a point or a line in UV space): unwrap it")
    if len(samples.texels) == 0:
        raise BakeError(f"UV map '{uv_name}' covers no texel at {resolution} x {resolution}: unwrap it into 0 to 1")
    if samples.overlapping:
        share = 100.0 * samples.overlapping / len(samples.texels)
        raise BakeError(
            f"UV map '{uv_name}' overlaps itself ({share:.1f} % of its texels lie under two faces: mirrored or "
            "tiled texture UVs): a lightmap needs each face on its own texels. Leave UV Map empty to make one"
        )
    if samples.outside:
        notes.append(f"{samples.outside} faces of UV map '{uv_name}' reach outside 0 to 1: those parts are not baked")
    if samples.degenerate:
        notes.append(f"{samples.degenerate} faces of UV map '{uv_name}' have no UV area and are not baked")
    seams = lightmap.seam_pairs(vertices, uvs, normals=world_normals)  # (smooth edges only)
    return TexelGeometry(uv_name, created, resolution, samples, seams, notes, uvs)


def texel_image(samples, coeffs, seams):
    """(res, res, n*n) float32 transfer image of a texel bake: the covered texels' coefficients,
    the gutter filled around each chart, the two sides of every seam made to agree."""
    covered = samples.covered()
    image = lightmap.dilate(samples.image(np.asarray(coeffs, np.float32)), covered)
    image = lightmap.fix_seams(image, seams, covered)
    return np.asarray(image, dtype=np.float32)


def prepare_texels(plan, mesh_eval, positions, settings, others, build_occluder, unwrapped):
    """The TexelGeometry of a plan, its samples under other surfaces (`others`: the scene's
    parts but the plan's own, [] when the scene does not shadow it) given zero normals (t = 0:
    they see that surface, as in Cycles), and its notes with the resolution. An open mesh also
    gets its back side's normals: the samples' turned over, zero where the back lies under
    another surface (docs/texels.md, "Back side")."""
    s = settings
    try:
        geometry = texel_geometry(plan, mesh_eval, positions, s.uv_map, s.resolution, s.texel_density, unwrapped)
    except BakeError as error:
        raise BakeError(f"'{plan.name}' {error}") from None
    samples = geometry.samples
    if back_side.is_open(plan.own_triangles):
        geometry.back_normals = -samples.normals
    vertices, triangles = concatenate_parts(others) if others else (None, np.zeros((0, 3)))
    if len(triangles):
        occluder = build_occluder(vertices, triangles)
        sides = [("", samples.normals), (" on their back", geometry.back_normals)]
        for where, normals in (side for side in sides if side[1] is not None):
            under = np.stack(
                [
                    contact.under_other_surfaces(p, n, plan.offset, occluder, vertices, triangles)
                    for p, n in zip(samples.positions, normals)
                ]
            )
            if under.any():
                normals[under] = 0.0
                count = int(under.any(axis=0).sum())
                geometry.notes.append(f"{count:,} texels lie under another surface{where} and are baked as shadowed")
    res = geometry.resolution
    geometry.notes.append(f"{res} x {res} texels of UV map '{geometry.uv_name}', {len(samples.texels):,} covered")
    return geometry


def texel_computation(plan, directions, settings, pool, hit_sink=None, normals=None):
    """The computation of a plan's texels: every texel's samples (core.transfer.split), or with
    settings.adaptive > 0 a lattice first and then the blocks that disagree (core.transfer.adaptive).
    An interreflected bake (a hit_sink) traces every texel: an interpolated texel has no hits, so
    adaptive sampling is off with bounces. normals: the samples' normals to bake for (default
    theirs; the back side's, plan.texels.back_normals, for its computation, which has no hits)."""
    samples = plan.texels.samples
    normals = samples.normals if normals is None else normals

    def make(which=slice(None)):
        return split.SplitComputation(
            samples.positions[:, which],
            normals[:, which],
            directions,
            settings.order,
            occluder=plan.occluder,
            offset=plan.offset,
            self_occludes=plan.self_occludes,
            other_boxes=plan.boxes,
            chunk_rays=settings.chunk_rays,
            threads=settings.threads,
            pool=pool,
            hit_sink=hit_sink,
        )

    if not settings.adaptive or hit_sink is not None:
        return make()
    lattice = adaptive.AdaptivePlan(samples.texels, normals, samples.resolution)
    return adaptive.AdaptiveComputation(lattice, make, settings.order, settings.adaptive)


def bakes_texels(plan, settings):
    """Whether the plan bakes texels: target TEXELS; with AUTO, a mesh too coarse for its size,
    with fewer vertices than one per 4 x 4 texels at the texel density (a single-quad wall, a
    low-poly prop), with or without bounces (a texel bake's texels are its bounce nodes)."""
    if settings.target != "AUTO":
        return settings.target == "TEXELS"
    corners = plan.own_vertices[plan.own_triangles].astype(np.float64)
    area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1).sum()
    return len(plan.mesh.vertices) < area * settings.texel_density**2 / 16.0


def within_memory(so_far, resolution, order, back=False):
    """so_far plus one more lightmap's texel_memory (with its back side's); raises BakeError past
    memory_budget()."""
    total = so_far + texel_memory(resolution, order, back=back)
    if total > memory_budget():
        raise BakeError(
            f"the lightmaps would take about {total / 2**30:.1f} GiB, more than a bake may use here "
            f"({memory_budget() / 2**30:.1f} GiB, half the memory): lower the resolution or the texel density"
        )
    return total
