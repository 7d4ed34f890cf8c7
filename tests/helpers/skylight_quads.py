"""A room of single-quad walls lit through a skylight, with a table and a box; its walls' split-light part in the view and traced."""

import math

import numpy as np

from helpers.worlds import bundled_hdri_path, new_world, use_image

SIZE = 512  # the camera image
S, H = 2.0, 3.0  # half the floor's side, the walls' height
SKYLIGHT = (-0.5, 0.5, 0.0, 1.0)  # x0, x1, y0, y1 of the hole in the ceiling
WALLS = ("back", "right", "left", "floor", "ceiling")
GRID = 60  # points per side of a wall's grid
LUMA = np.array([0.2126, 0.7152, 0.0722])
DENSE_SAMPLES = 1024  # a light's power cells in the reference (the viewport and api.shade use 16)


def _faces_object(bpy, name, quads, inward):
    """One mesh object of single quads, each turned to face `inward`."""
    verts, faces = [], []
    for quad in quads:
        c = np.asarray(quad, dtype=np.float64)
        if np.cross(c[1] - c[0], c[3] - c[0]) @ (np.asarray(inward) - c.mean(axis=0)) < 0.0:
            c = c[::-1]
        faces.append(tuple(range(len(verts), len(verts) + 4)))
        verts += [tuple(p) for p in c]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _cube(bpy, name, centre, size):
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=centre)
    obj = bpy.context.object
    obj.name = name
    obj.scale = size
    bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
    return obj


def build(bpy, scene, hdri="courtyard"):
    """The room under a bundled HDRI, a white material on everything, a camera inside looking at
    the back-right corner; -> the objects (walls first, in WALLS order)."""
    use_image(new_world(bpy, scene), bpy.data.images.load(bundled_hdri_path(hdri)))
    mid = (0.0, 0.0, H / 2)
    x0, x1, y0, y1 = SKYLIGHT
    quads = {
        "back": [[(-S, S, 0), (S, S, 0), (S, S, H), (-S, S, H)]],
        "right": [[(S, -S, 0), (S, S, 0), (S, S, H), (S, -S, H)]],
        "left": [[(-S, -S, 0), (-S, S, 0), (-S, S, H), (-S, -S, H)]],
        "floor": [[(-S, -S, 0), (S, -S, 0), (S, S, 0), (-S, S, 0)]],
        "ceiling": [
            [(-S, -S, H), (S, -S, H), (S, y0, H), (-S, y0, H)],
            [(-S, y1, H), (S, y1, H), (S, S, H), (-S, S, H)],
            [(-S, y0, H), (x0, y0, H), (x0, y1, H), (-S, y1, H)],
            [(x1, y0, H), (S, y0, H), (S, y1, H), (x1, y1, H)],
        ],
        "front": [[(-S, -S, 0), (S, -S, 0), (S, -S, H), (-S, -S, H)]],
    }
    objects = [_faces_object(bpy, name, q, mid) for name, q in quads.items()]
    objects.append(_cube(bpy, "box", (1.0, -0.6, 0.3), (0.6, 0.6, 0.6)))
    objects.append(_cube(bpy, "table", (-0.6, 0.8, 0.75), (1.2, 0.8, 0.05)))
    material = bpy.data.materials.new("white")
    for obj in objects:
        obj.data.materials.append(material)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera)
    camera.location = (-1.7, -1.7, 1.5)
    camera.rotation_euler = (math.radians(88.0), 0.0, math.radians(-45.0))
    camera.data.lens = 14.0
    scene.camera = camera
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    scene.prt_display.albedo_source = "WHITE"
    bpy.context.view_layer.update()
    return objects


def baked_views(bpy, hdri="courtyard", shade_sky=False):
    """The room built in an empty file, baked (order 2, 64 directions: the tests read the lights'
    part, which the bake does not change) and drawn with the HDRI's split lights and with none:
    (scene, objects, lights, image, sky image, and with `shade_sky` api.shade of each wall without
    the lights, else None)."""
    import prt_addon.api as api
    from prt_addon.blender.scene import lighting

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    objects = build(bpy, scene, hdri)
    api.bake(objects, order=2, samples=64)
    api.project_world(scene, 2, split_lights=True)
    lights = lighting.world_lights(scene)
    image = api.render_view(scene, SIZE, SIZE)
    lighting.set_lights_override(scene, [])
    try:
        sky = api.render_view(scene, SIZE, SIZE)
        walls = {obj.name: api.shade(obj, scene) for obj in objects[: len(WALLS)]} if shade_sky else None
    finally:
        lighting.set_lights_override(scene, None)
    return scene, objects, lights, image, sky, walls


def dense_lights(scene, lights):
    """The scene's split lights again, each with DENSE_SAMPLES power cells of its own texels (the
    same regions, powers and directions as `lights`, which must be unrotated)."""
    from prt_addon.blender.world import pixels
    from prt_addon.core.lights.extraction import extract_lights

    node = next(n for n in scene.world.node_tree.nodes if n.type == "TEX_ENVIRONMENT")
    settings = scene.prt_world
    threshold = None if settings.auto_threshold else settings.light_threshold
    _, dense = extract_lights(
        pixels.read_image_pixels(node.image), threshold, settings.max_lights, samples=DENSE_SAMPLES
    )
    assert len(dense) == len(lights)
    for a, b in zip(dense, lights):
        np.testing.assert_allclose(a.power, b.power, rtol=1e-6)
        assert a.direction @ b.direction > 1.0 - 1e-9
    return dense


def _wall_grid(obj):
    """(points (GRID^2, 3), unit normal, (i, j) grid indices) over the first quad of obj, 3 % in from its edges."""
    mw = np.array(obj.matrix_world)
    co = np.array([v.co for v in obj.data.vertices])[:4] @ mw[:3, :3].T + mw[:3, 3]
    normal = np.cross(co[1] - co[0], co[3] - co[0])
    normal /= np.linalg.norm(normal)
    i, j = np.meshgrid(np.arange(GRID), np.arange(GRID), indexing="ij")
    u = (0.03 + 0.94 * i.ravel() / (GRID - 1))[:, None]
    v = (0.03 + 0.94 * j.ravel() / (GRID - 1))[:, None]
    points = (1 - u) * (1 - v) * co[0] + u * (1 - v) * co[1] + u * v * co[2] + (1 - u) * v * co[3]
    return points, normal, (i.ravel(), j.ravel())


def _traced(points, normals, lights, occluder):
    """(P, 3) the lights' E/pi at the points, their visibility traced one ray per sample."""
    from prt_addon.core.lights import visibility

    seen = visibility.light_visibility(points, normals, lights, occluder, offset=1e-3)
    return visibility.light_irradiance(normals, lights, seen)


def _occluder(bpy, scene):
    """(Embree occluder of the scene's casters, {object name: its triangles' index range})."""
    from prt_addon.blender.display import shadows
    from prt_addon.core.trace.raytrace import EmbreeOccluder

    depsgraph = bpy.context.evaluated_depsgraph_get()
    casters = shadows.caster_objects(scene)
    occluder = EmbreeOccluder(*shadows.caster_triangles(casters, depsgraph))
    ranges, first = {}, 0
    for obj in casters:
        count = len(shadows.caster_triangles([obj], depsgraph)[1])
        ranges[obj.name] = (first, first + count)
        first += count
    return occluder, ranges


def _first_hits(occluder, eye, points):
    """The index of the triangle the camera's ray towards each point hits first."""
    towards = points - eye
    return occluder.nearest_triangles(
        np.tile(eye, (len(points), 1)).astype(np.float32),
        (towards / np.linalg.norm(towards, axis=1, keepdims=True)).astype(np.float32),
    )


def wall_samples(bpy, scene, lights_image, sky_image, lights, dense):
    """{wall: dict} at the wall's grid points the camera sees: 'view' the luminance of the view's
    split-light part (lights_image - sky_image), 'shade' api.shade's model of it (16 rays, one per
    sample, traced at the points), 'dense' the same over DENSE_SAMPLES rays per light, 'total'
    the view's luminance, 'grid' the points' (i, j)."""
    from prt_addon.blender.display import offscreen

    occluder, ranges = _occluder(bpy, scene)
    view, proj = offscreen.camera_matrices(scene, SIZE, SIZE)
    eye = np.array(scene.camera.matrix_world.translation)
    out = {}
    for name in WALLS:
        points, normal, grid = _wall_grid(bpy.data.objects[name])
        clip = np.c_[points, np.ones(len(points))] @ (proj @ view).T
        ndc = clip[:, :2] / clip[:, 3:4]
        rows = np.floor((1.0 - ndc[:, 1]) * 0.5 * SIZE).astype(int)
        cols = np.floor((ndc[:, 0] + 1.0) * 0.5 * SIZE).astype(int)
        seen = (clip[:, 3] > 0) & (rows >= 0) & (rows < SIZE) & (cols >= 0) & (cols < SIZE)
        first_hit = _first_hits(occluder, eye, points)
        lo, hi = ranges[name]
        seen &= (first_hit >= lo) & (first_hit < hi) & ((points - eye) @ normal < 0.0)
        p, n = points[seen], np.tile(normal, (int(seen.sum()), 1))
        r, c = rows[seen], cols[seen]

        out[name] = {
            "view": (lights_image[r, c, :3] - sky_image[r, c, :3]) @ LUMA,
            "shade": _traced(p, n, lights, occluder) @ LUMA,
            "dense": _traced(p, n, dense, occluder) @ LUMA,
            "total": lights_image[r, c, :3] @ LUMA,
            "grid": (grid[0][seen], grid[1][seen]),
        }
    return out


def second_differences(wall, key):
    """RMS of the second differences of wall[key] (a wall of wall_samples) along the wall: between
    neighbouring grid points of one row (the quad's first edge: across the wall at one height),
    over the triples the camera sees. A smooth gradient has nearly none; a step, a streak or a
    ripple at the grid's spacing (6.4 cm on a 4 m wall) adds its height."""
    i, j = wall["grid"]
    grid = np.full((GRID, GRID), np.nan)
    grid[i, j] = wall[key]
    second = grid[2:] - 2.0 * grid[1:-1] + grid[:-2]
    return float(np.sqrt(np.nanmean(second**2)))


def relative_rms(values, reference):
    """RMS of values - reference over the RMS of the reference."""
    return float(np.sqrt(np.mean((values - reference) ** 2)) / max(np.sqrt(np.mean(reference**2)), 1e-12))


# Joins of the room: (receiver, a, b, into the receiver from the join, the receiver's normal).
JOINS = {
    "back/ceiling": ("back", (-S, S, H), (S, S, H), (0, 0, -1), (0, -1, 0)),
    "back/floor": ("back", (-S, S, 0), (S, S, 0), (0, 0, 1), (0, -1, 0)),
    "back/right": ("back", (S, S, 0), (S, S, H), (-1, 0, 0), (0, -1, 0)),
    "left/ceiling": ("left", (-S, -S, H), (-S, S, H), (0, 0, -1), (1, 0, 0)),
    "left/floor": ("left", (-S, -S, 0), (-S, S, 0), (0, 0, 1), (1, 0, 0)),
    "right/ceiling": ("right", (S, -S, H), (S, S, H), (0, 0, -1), (-1, 0, 0)),
    "right/back": ("right", (S, S, 0), (S, S, H), (0, -1, 0), (-1, 0, 0)),
    "floor/back": ("floor", (-S, S, 0), (S, S, 0), (0, -1, 0), (0, 0, 1)),
    "floor/right": ("floor", (S, -S, 0), (S, S, 0), (-1, 0, 0), (0, 0, 1)),
    "right/floor": ("right", (S, -S, 0), (S, S, 0), (0, 0, 1), (-1, 0, 0)),
    "floor/box": ("floor", (0.7, -0.9, 0), (1.3, -0.9, 0), (0, -1, 0), (0, 0, 1)),
    "box/floor (west side)": ("box", (0.7, -0.9, 0), (0.7, -0.3, 0), (0, 0, 1), (-1, 0, 0)),
    "box/floor (south side)": ("box", (0.7, -0.9, 0), (1.3, -0.9, 0), (0, 0, 1), (0, -1, 0)),
}


def join_bands(bpy, scene, lights_image, sky_image, dense, distances):
    """{join: (view, traced)}, each (len(distances),): the luminance of the view's split-light
    part and of the dense lights traced, averaged over 40 points along the join (its middle 80 %)
    at each distance from it on the receiver, the points the camera sees."""
    from prt_addon.blender.display import offscreen

    occluder, ranges = _occluder(bpy, scene)
    view, proj = offscreen.camera_matrices(scene, SIZE, SIZE)
    eye = np.array(scene.camera.matrix_world.translation)
    t = np.linspace(0.1, 0.9, 40)[:, None]
    out = {}
    for key, (name, a, b, inward, normal) in JOINS.items():
        a, b, inward = np.asarray(a, float), np.asarray(b, float), np.asarray(inward, float)
        views, traced = [], []
        for d in distances:
            p = a + t * (b - a) + d * inward
            n = np.tile(np.asarray(normal, float), (len(p), 1))
            clip = np.c_[p, np.ones(len(p))] @ (proj @ view).T
            ndc = clip[:, :2] / clip[:, 3:4]
            seen = (clip[:, 3] > 0) & (np.abs(ndc) < 0.999).all(axis=1) & ((p - eye) @ n[0] < 0.0)
            first_hit = _first_hits(occluder, eye, p)  # (the walls' own hits are unsure at grazing views)
            for other in {"box", "table"} - {name}:
                seen &= (first_hit < ranges[other][0]) | (first_hit >= ranges[other][1])
            assert seen.sum() >= 5, key
            rows = np.floor((1.0 - ndc[seen, 1]) * 0.5 * SIZE).astype(int)
            cols = np.floor((ndc[seen, 0] + 1.0) * 0.5 * SIZE).astype(int)
            views.append(float(((lights_image[rows, cols, :3] - sky_image[rows, cols, :3]) @ LUMA).mean()))
            traced.append(float((_traced(p[seen], n[seen], dense, occluder) @ LUMA).mean()))
        out[key] = (np.array(views), np.array(traced))
    return out
