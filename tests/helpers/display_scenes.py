"""Display scenes: a camera, an environment world, a baked sphere, a light set on the scene, transfer written by hand."""

import math
import warnings

import numpy as np

from prt_addon.core.sh import analytic, basis as sh


def write_bake(obj, transfer, order, domain="POINT"):
    """Write (elements, order**2) transfer into prt_tKK + mesh["prt_bake"] per docs/storage.md."""
    mesh = obj.data
    n2 = order * order
    count = (n2 + 3) // 4
    padded = np.zeros((transfer.shape[0], 4 * count), dtype=np.float32)
    padded[:, :n2] = transfer
    names = [f"prt_t{k:02d}" for k in range(count)]
    for name in names:
        mesh.color_attributes.new(name, "FLOAT_COLOR", domain)
    for k, name in enumerate(names):  # look up by name after all new() calls
        mesh.attributes[name].data.foreach_set("color", np.ascontiguousarray(padded[:, 4 * k : 4 * k + 4]).ravel())
    mesh["prt_bake"] = {
        "order": order,
        "count": count,
        "domain": domain,
        "samples": 0,
        "direction_set": "analytic",
        "seed": 0,
        "shadows": False,
        "backend": "NONE",
        "fingerprint": fingerprint(mesh),
        "seconds": 0.0,
        "rays_traced": 0,
        "rays_skipped": 0,
        "error_estimate": 0.0,
    }


def fingerprint(mesh):
    from prt_addon.blender.scene.mesh_read import topology_fingerprint

    return topology_fingerprint(mesh)


def clamped_cosine_rows(normals, order):
    """(N, order**2): analytic.clamped_cosine_coeffs(order, n) for every row n, vectorised."""
    zonal = analytic.clamped_cosine_zonal(order)
    bands = sh.band_of_index(order)
    scale = np.sqrt(4.0 * np.pi / (2.0 * bands + 1.0)) * zonal[bands]
    return sh.sh_basis(normals, order) * scale[None, :]


def make_sphere(bpy, name="Sphere", segments=48, rings=24, radius=1.0):
    import bmesh

    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=segments, v_segments=rings, radius=radius)
    bm.to_mesh(mesh)
    bm.free()
    mesh.shade_smooth()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def local_positions(mesh):
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.attributes["position"].data.foreach_get("vector", co)
    return co.reshape(-1, 3).astype(np.float64)


def bake_sphere(bpy, order, **kw):
    obj = make_sphere(bpy, **kw)
    normals = local_positions(obj.data)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    write_bake(obj, clamped_cosine_rows(normals, order), order)
    return obj


def sun_sky_light(order):
    """A warm sun along +X (cap of 0.3 rad) plus a bluish constant sky, (order**2, 3)."""
    light = analytic.cap_coeffs(order, (1.0, 0.0, 0.0), 0.3, radiance=(20.0, 14.0, 7.0))
    light[0] += np.array([0.2, 0.3, 0.5]) * np.sqrt(4.0 * np.pi)
    return light


def add_camera(bpy, scene, location=(0.0, -6.0, 0.0), euler=(math.pi / 2, 0.0, 0.0), size=256):
    cam_data = bpy.data.cameras.new("Cam")
    cam = bpy.data.objects.new("Cam", cam_data)
    scene.collection.objects.link(cam)
    cam.location = location
    cam.rotation_euler = euler
    scene.camera = cam
    scene.render.resolution_x = size
    scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    return cam


def add_env_world(bpy, scene):
    """A world Background <- Environment Texture (no image needed: lighting is injected)."""
    world = bpy.data.worlds.new("World")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        world.use_nodes = True
    tree = world.node_tree
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    background = tree.nodes.get("Background")
    tree.links.new(env.outputs["Color"], background.inputs["Color"])
    scene.world = world
    return world


def vertex_pixels(bpy, obj, scene, width, height):
    """(cols, rows, visible): each vertex's pixel (top row 0) and whether it faces the camera."""
    bpy.context.view_layer.update()
    mw = np.array(obj.matrix_world)
    p_local = local_positions(obj.data)
    p = p_local @ mw[:3, :3].T + mw[:3, 3]
    cam = scene.camera
    depsgraph = bpy.context.evaluated_depsgraph_get()
    proj = np.array(cam.calc_matrix_camera(depsgraph, x=width, y=height))
    view = np.array(cam.matrix_world.inverted())
    clip = np.c_[p, np.ones(len(p))] @ (proj @ view).T
    ndc = clip[:, :3] / clip[:, 3:4]
    cols = np.floor((ndc[:, 0] + 1.0) * 0.5 * width).astype(int)
    rows = np.floor((1.0 - ndc[:, 1]) * 0.5 * height).astype(int)
    normals = p - mw[:3, 3]
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    to_cam = np.array(cam.matrix_world.translation) - p
    to_cam /= np.linalg.norm(to_cam, axis=1, keepdims=True)
    visible = (np.einsum("ij,ij->i", normals, to_cam) > 0.35) & (cols >= 0) & (cols < width)
    visible &= (rows >= 0) & (rows < height)
    return cols, rows, visible


def sample_at_vertices(bpy, obj, scene, image):
    h, w = image.shape[:2]
    cols, rows, visible = vertex_pixels(bpy, obj, scene, w, h)
    return image[rows[visible], cols[visible], :3], visible


def set_light(scene, light):
    from prt_addon.blender.scene import lighting

    lighting.set_light_override(scene, light)
