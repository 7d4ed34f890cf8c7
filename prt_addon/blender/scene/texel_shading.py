"""`shade` for texel bakes: E/pi per texel of the transfer image, the split lights traced at each texel's samples."""

import numpy as np

from ...core.lights import visibility as light_visibility
from ...core.transfer import lightmap, texels
from ...core.transfer.mesh import matrix_to_numpy
from . import mesh_read, texel_storage
from .light_shading import RAYS_PER_LIGHT, scene_occluder


def texel_samples(obj_eval, bake):
    """The texel samples of a texel bake as the bake placed them (world space)."""
    mesh = obj_eval.data
    matrix = matrix_to_numpy(obj_eval.matrix_world)
    _corners, _vertices, world, normals = mesh_read.world_triangles(mesh, matrix)
    corner_uvs = mesh_read.read_corner_uvs(mesh, bake.uv_map)
    corners, _faces = mesh_read.read_triangle_corners(mesh)
    inset = float(bake.record.get("offset", 0.0))
    return texels.texel_samples(corner_uvs[corners].astype(np.float64), world, normals, bake.resolution, inset=inset)


def sky_radiance(bake, light, bounce_light=None, side="FRONT"):
    """(res, res, 3) max(sum_i L_i t_i, 0) per texel for a local-frame light (n*n, 3); with
    bounces t = direct + bounced, the bounced part lit by `bounce_light` (default: light), as
    lighting.shade does for vertex bakes. side "BACK": the back side's image (direct only)."""
    n2 = bake.order * bake.order
    back = side == "BACK"
    read = texel_storage.read_texel_back if back else texel_storage.read_texel_transfer
    transfer = read(bake).reshape(-1, n2).astype(np.float64)
    res = bake.resolution
    radiance = transfer @ light[:n2]
    bounced = None if back else texel_storage.read_texel_bounce(bake)
    if bounced is not None:
        full = np.asarray(light if bounce_light is None else bounce_light, dtype=np.float64)[:n2]
        bounced = bounced.reshape(res * res, bake.channels, n2)
        for c in range(3):  # one bounced vector per channel, or one for all (grey surfaces)
            radiance[:, c] += bounced[:, min(c, bake.channels - 1)].astype(np.float64) @ full[:, c]
    return np.maximum(radiance, 0.0).reshape(res, res, 3)


def light_radiance(obj, depsgraph, lights, bake, rays_per_light=RAYS_PER_LIGHT, side="FRONT"):
    """(res, res, 3) radiance of the split lights per texel (white albedo): the mean over each
    texel's samples of P/pi max(0, n.s) V, shadowed as the bake was; the gutter filled. side
    "BACK": on the samples' flipped normals, the ray origins offset to the back."""
    if not lights:
        return np.zeros((bake.resolution, bake.resolution, 3))
    obj_eval = obj.evaluated_get(depsgraph)
    samples = texel_samples(obj_eval, bake)
    record = bake.record
    offset = float(record.get("offset", 0.0))
    occluder = None
    if bool(record.get("shadows", True)):
        occluder = scene_occluder(depsgraph, obj_eval if bool(record.get("self_shadow_only", False)) else None)
    count = len(samples.positions)
    total = np.zeros((len(samples.texels), 3))
    rays = max(1, -(-rays_per_light // count))  # the light's rays shared between the samples
    flip = -1.0 if side == "BACK" else 1.0
    for points, normals in zip(samples.positions, flip * samples.normals):
        visibility = None
        if occluder is not None:
            visibility = light_visibility.light_visibility(
                points, normals, lights, occluder, rays_per_light=rays, offset=offset
            )
        total += light_visibility.light_irradiance(normals, lights, visibility)
    return lightmap.dilate(samples.image(total / count), samples.covered())  # (the bake's gutter)
