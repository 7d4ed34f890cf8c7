"""Shadow scenes: a ground grid under suns, rendered offscreen, and its pixels."""

import numpy as np

from helpers.display_scenes import clamped_cosine_rows, write_bake

SKY = np.array([0.2, 0.3, 0.5])
POWER = np.array([3.0, 2.5, 2.0])
SIZE = 256


def sky_light(order=3):
    light = np.zeros((order * order, 3))
    light[0] = SKY * np.sqrt(4.0 * np.pi)
    return light


def make_ground(bpy, scene, half=4.0, segments=64):
    """A flat grid at z = 0 of side 2 * half, baked with the clamped cosine about +Z."""
    import bmesh

    mesh = bpy.data.meshes.new("Ground")
    bm = bmesh.new()
    bmesh.ops.create_grid(bm, x_segments=segments, y_segments=segments, size=half)
    bm.to_mesh(mesh)
    bm.free()
    obj = bpy.data.objects.new("Ground", mesh)
    scene.collection.objects.link(obj)
    normals = np.tile([0.0, 0.0, 1.0], (len(mesh.vertices), 1))
    write_bake(obj, clamped_cosine_rows(normals, 3), 3)
    return obj


def make_box(bpy, scene, centre=(0.0, 0.0, 1.0), size=1.0):
    import bmesh

    mesh = bpy.data.meshes.new("Box")
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=size)
    bm.to_mesh(mesh)
    bm.free()
    obj = bpy.data.objects.new("Box", mesh)
    scene.collection.objects.link(obj)
    obj.location = centre
    return obj


def set_suns(scene, lights):
    from prt_addon.blender.scene import lighting

    lighting.set_lights_override(scene, lights)


def ground_pixels(scene, points):
    """(rows, cols) of world points (top row 0) in the SIZE x SIZE camera image."""
    from prt_addon.blender.display import offscreen

    view, proj = offscreen.camera_matrices(scene, SIZE, SIZE)
    clip = np.c_[points, np.ones(len(points))] @ (proj @ view).T
    ndc = clip[:, :2] / clip[:, 3:4]
    cols = np.floor((ndc[:, 0] + 1.0) * 0.5 * SIZE).astype(int)
    rows = np.floor((1.0 - ndc[:, 1]) * 0.5 * SIZE).astype(int)
    return rows, cols


def render(scene):
    import prt_addon.api as api

    return api.render_view(scene, SIZE, SIZE)


def cap_directions(centre, radius, count=4000):
    """(count, 3) unit directions spread evenly over the cap (a Fibonacci spiral in its frame)."""
    i = np.arange(count) + 0.5
    cos_t = 1.0 - (1.0 - np.cos(radius)) * i / count
    phi = i * np.pi * (3.0 - np.sqrt(5.0))
    sin_t = np.sqrt(1.0 - cos_t**2)
    local = np.c_[sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t]
    z = np.asarray(centre, dtype=np.float64) / np.linalg.norm(centre)
    x = np.cross([0.0, 1.0, 0.0] if abs(z[1]) < 0.9 else [1.0, 0.0, 0.0], z)
    x /= np.linalg.norm(x)
    return local @ np.array([x, np.cross(z, x), z])


def cap_light(centre, radius):
    """The Light extraction makes of a uniform cap: 16 power cells (core.lights.samples), its
    moment radius (1 - cos R = 2 (1 - |mean|)) and its power-median angle; and the cap's directions."""
    from prt_addon.core.lights.extraction import Light
    from prt_addon.core.lights.samples import median_angle, region_samples

    dirs = cap_directions(centre, radius)
    weights = np.full(len(dirs), 1.0 / len(dirs))
    samples, sample_weights = region_samples(dirs * weights[:, None], weights)
    mean = dirs.mean(axis=0)
    direction = mean / np.linalg.norm(mean)
    angle = float(np.arccos(2.0 * np.linalg.norm(mean) - 1.0))
    shadow = median_angle(dirs * weights[:, None], weights, direction)
    return Light(direction, POWER, angle, samples=samples, weights=sample_weights, shadow_angle=shadow), dirs
