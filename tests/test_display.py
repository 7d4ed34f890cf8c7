"""Live PRT display: shader, offscreen render against api.shade, lighting and object
rotation, handler cleanup, save/reload. Needs the GPU initialised headless.

Baked data is written here by a test helper that follows docs/storage.md exactly (unshadowed
transfer of a sphere = the clamped cosine about the local normal), independent of the bake.
"""

import math
import warnings

import numpy as np
import pytest

pytestmark = [pytest.mark.blender, pytest.mark.gpu]

from prt_addon.core import analytic, sh  # noqa: E402


# ---------------------------------------------------------------------------------------------
# Helpers
# ---------------------------------------------------------------------------------------------


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
    from prt_addon.blender.mesh_read import topology_fingerprint

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


# ---------------------------------------------------------------------------------------------
# Fixtures
# ---------------------------------------------------------------------------------------------


@pytest.fixture
def lit_scene(bpy_module, empty_scene, gpu_ready):
    scene = empty_scene
    add_env_world(bpy_module, scene)
    add_camera(bpy_module, scene)
    return scene


def set_light(scene, light):
    from prt_addon.blender.display import lighting

    lighting.set_light_override(scene, light)


# ---------------------------------------------------------------------------------------------
# Tests
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("order", [1, 2, 3, 4, 7, 8, 12, 16])
def test_shader_compiles_for_every_order(gpu_ready, order):
    from prt_addon.blender import storage
    from prt_addon.blender.display import shader as display_shader

    count = storage.attribute_count(order)
    shader = display_shader.get_shader(count)
    assert shader is not None
    # Orders 1..7 fit in vertex attributes (pos + albedo + 14); 8 and up use the texture path.
    assert display_shader.shader_mode(count) == ("ATTR" if order <= 7 else "TEXTURE")


def test_shade_matches_world_frame_expectation(bpy_module, lit_scene):
    """shade() of a rotated, translated, uniformly scaled sphere equals the clamped-cosine
    convolution of the world light at each world normal, computed without the local frame."""
    import prt_addon.api as api

    order = 4
    obj = bake_sphere(bpy_module, order, segments=16, rings=8)
    obj.rotation_euler = (0.4, -1.1, 2.3)
    obj.location = (0.3, 0.2, -0.1)
    obj.scale = (1.7, 1.7, 1.7)
    bpy_module.context.view_layer.update()
    light = sun_sky_light(order)
    set_light(lit_scene, light)
    got = api.shade(obj, lit_scene)
    r = np.array(obj.matrix_world.to_3x3().normalized())
    n_local = local_positions(obj.data)
    n_world = (n_local / np.linalg.norm(n_local, axis=1, keepdims=True)) @ r.T
    expected = np.maximum(clamped_cosine_rows(n_world, order) @ light, 0.0)
    assert got.shape == (len(obj.data.vertices), 3)
    np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-6)
    # Non-uniform scale does not change the shading (only the rotation part is used).
    obj.scale = (0.5, 2.0, 1.3)
    bpy_module.context.view_layer.update()
    np.testing.assert_allclose(api.shade(obj, lit_scene), got, rtol=1e-5, atol=1e-6)
    # A mirrored object: the orthogonal part is a reflection, handled by the SH parity.
    obj.scale = (-1.0, 1.0, 1.0)
    bpy_module.context.view_layer.update()
    m = np.array(obj.matrix_world.to_3x3())
    n_mirror = (n_local / np.linalg.norm(n_local, axis=1, keepdims=True)) @ m.T
    expected_mirror = np.maximum(clamped_cosine_rows(n_mirror, order) @ light, 0.0)
    np.testing.assert_allclose(api.shade(obj, lit_scene), expected_mirror, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("order", [3, 8, 16])
def test_offscreen_render_agrees_with_shade(bpy_module, lit_scene, order):
    """The GPU image at each visible vertex equals api.shade there (order 3: vertex attributes,
    orders 8 and 16: transfer texture)."""
    import prt_addon.api as api

    obj = bake_sphere(bpy_module, order)
    obj.rotation_euler = (0.3, 0.2, 0.7)  # the local frame is not the world frame
    light = sun_sky_light(order)
    set_light(lit_scene, light)
    lit_scene.prt_display.albedo_source = "WHITE"
    image = api.render_view(lit_scene, 512, 512)
    assert image.shape == (512, 512, 4) and image.dtype == np.float32
    expected = api.shade(obj, lit_scene)
    got, visible = sample_at_vertices(bpy_module, obj, lit_scene, image)
    assert visible.sum() > 200
    want = expected[visible]
    err = np.abs(got - want) / (np.abs(want) + 0.05)
    assert np.median(err) < 0.01, np.median(err)
    assert err.max() < 0.05, err.max()
    # Background stays transparent, the sphere is opaque.
    assert image[0, 0, 3] == 0.0 and image[256, 256, 3] == 1.0


def test_material_albedo_multiplies(bpy_module, lit_scene):
    import prt_addon.api as api

    obj = bake_sphere(bpy_module, 3, segments=24, rings=12)
    mat = bpy_module.data.materials.new("Red")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        mat.use_nodes = True
    mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.5, 0.25, 0.1, 1.0)
    obj.data.materials.append(mat)
    set_light(lit_scene, sun_sky_light(3))
    lit_scene.prt_display.albedo_source = "WHITE"
    white = api.render_view(lit_scene, 128, 128)
    lit_scene.prt_display.albedo_source = "MATERIAL"
    red = api.render_view(lit_scene, 128, 128)
    mask = white[..., 3] > 0
    np.testing.assert_allclose(red[mask, :3], white[mask, :3] * [0.5, 0.25, 0.1], rtol=1e-5, atol=1e-6)


def _bright_side(values, normals, axis):
    """Mean luminance on the +axis side minus that on the -axis side."""
    lum = values @ np.array([0.2126, 0.7152, 0.0722])
    d = normals @ np.asarray(axis, dtype=np.float64)
    return lum[d > 0.5].mean() - lum[d < -0.5].mean()


def test_lighting_rotation_180_moves_bright_side(bpy_module, lit_scene):
    import prt_addon.api as api
    from prt_addon.blender.world import nodes as world_nodes

    order = 4
    obj = bake_sphere(bpy_module, order)
    set_light(lit_scene, sun_sky_light(order))
    lit_scene.prt_display.albedo_source = "WHITE"
    normals = local_positions(obj.data)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    before = api.shade(obj, lit_scene)
    image_before = api.render_view(lit_scene, 256, 256)
    assert _bright_side(before, normals, (1, 0, 0)) > 0.5  # the sun is along +X

    assert bpy_module.ops.prt.set_light_rotation(rotation=(0.0, 0.0, math.pi)) == {"FINISHED"}
    mapping = world_nodes.find_mapping_node(lit_scene.world)
    assert mapping is not None  # the sidebar operator created the world's Mapping node
    assert tuple(mapping.inputs["Rotation"].default_value) == pytest.approx((0.0, 0.0, math.pi))
    after = api.shade(obj, lit_scene)
    image_after = api.render_view(lit_scene, 256, 256)
    assert _bright_side(after, normals, (1, 0, 0)) < -0.5
    # The sphere is symmetric: the 180-degree rotation mirrors the shading x -> -x, y -> -y.
    mirror = np.argmin(
        np.linalg.norm(normals[:, None, :2] + normals[None, :, :2], axis=2)
        + np.abs(normals[:, None, 2] - normals[None, :, 2]),
        axis=1,
    )
    np.testing.assert_allclose(after, before[mirror], rtol=1e-4, atol=1e-4)

    # In the camera view (+X to the right) the bright half moves from right to left.
    def halves(img):
        lum = img[..., :3] @ np.array([0.2126, 0.7152, 0.0722])
        return lum[:, :128].sum(), lum[:, 128:].sum()

    left, right = halves(image_before)
    assert right > 2.0 * left
    left, right = halves(image_after)
    assert left > 2.0 * right


def test_editing_mapping_node_directly_updates_display(bpy_module, lit_scene):
    """POINT Mapping +90 deg about Z: the world is image(R d), so the +X sun appears at -Y
    (docs/world.md, measured against Cycles)."""
    import prt_addon.api as api
    from prt_addon.blender.world import nodes as world_nodes

    order = 4
    obj = bake_sphere(bpy_module, order)
    set_light(lit_scene, sun_sky_light(order))
    lit_scene.prt_display.albedo_source = "WHITE"
    node = world_nodes.ensure_mapping_node(lit_scene.world)
    node.inputs["Rotation"].default_value = (0.0, 0.0, math.pi / 2)
    assert world_nodes.mapping_rotation_euler(lit_scene.world) == pytest.approx((0.0, 0.0, math.pi / 2))
    normals = local_positions(obj.data)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    values = api.shade(obj, lit_scene)
    brightest = normals[np.argmax(values[:, 0])]
    assert brightest @ np.array([0.0, -1.0, 0.0]) > 0.95
    # The drawn image turned with the node as api.shade did (a stale rotation would put the
    # bright side elsewhere and fail this comparison at the vertices).
    image = api.render_view(lit_scene, 128, 128)
    got, visible = sample_at_vertices(bpy_module, obj, lit_scene, image)
    want = values[visible]
    err = np.abs(got - want) / (np.abs(want) + 0.05)
    assert np.median(err) < 0.01, np.median(err)


def test_projected_world_turns_through_a_mapping_node_added_by_hand(bpy_module, lit_scene):
    """The real path, no injected light: an image world projected without a Mapping node, then a
    Mapping node added and turned by hand. The display, api.shade and api.world_lighting all
    follow it, and the +X sun of the image lights the sphere from -Y (POINT, +90 deg about Z)."""
    import prt_addon.api as api
    from test_world import add_mapping, float_image, image_of, use_image

    order = 4
    world = lit_scene.world
    for node in [n for n in world.node_tree.nodes if n.bl_idname == "ShaderNodeTexEnvironment"]:
        world.node_tree.nodes.remove(node)
    env = use_image(world, float_image(bpy_module, "sun_sky", image_of(sun_sky_light(order), 64, 128)))
    api.project_world(lit_scene, order)
    obj = bake_sphere(bpy_module, order)
    lit_scene.prt_display.albedo_source = "WHITE"
    normals = local_positions(obj.data)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    before = api.shade(obj, lit_scene)
    assert normals[np.argmax(before[:, 0])] @ np.array([1.0, 0.0, 0.0]) > 0.95
    add_mapping(world, env, euler=(0.0, 0.0, math.pi / 2))
    values = api.shade(obj, lit_scene)
    assert normals[np.argmax(values[:, 0])] @ np.array([0.0, -1.0, 0.0]) > 0.95
    image = api.render_view(lit_scene, 128, 128)
    got, visible = sample_at_vertices(bpy_module, obj, lit_scene, image)
    want = values[visible]
    err = np.abs(got - want) / (np.abs(want) + 0.05)
    assert np.median(err) < 0.01, np.median(err)


def test_object_rotation_equals_opposite_lighting_rotation(bpy_module, lit_scene):
    """Object rotated by Euler e, lighting fixed == object fixed, world rotated by R(e)^-1 (a POINT
    Mapping node with the same Euler e, since the world is image(R d)): identical shading."""
    import prt_addon.api as api

    order = 5
    euler = (0.7, -0.4, 1.9)
    obj = bake_sphere(bpy_module, order, segments=24, rings=12)
    set_light(lit_scene, sun_sky_light(order))
    lit_scene.prt_display.albedo_source = "WHITE"
    obj.rotation_euler = euler
    bpy_module.context.view_layer.update()
    rotated_object = api.shade(obj, lit_scene)
    img_obj = api.render_view(lit_scene, 256, 256)
    got_obj, vis_obj = sample_at_vertices(bpy_module, obj, lit_scene, img_obj)

    obj.rotation_euler = (0.0, 0.0, 0.0)
    bpy_module.context.view_layer.update()
    unrotated = api.shade(obj, lit_scene)
    bpy_module.ops.prt.set_light_rotation(rotation=euler)
    rotated_light = api.shade(obj, lit_scene)
    img_light = api.render_view(lit_scene, 256, 256)
    got_light, vis_light = sample_at_vertices(bpy_module, obj, lit_scene, img_light)

    assert np.abs(rotated_object - unrotated).max() > 0.3  # the rotation matters
    np.testing.assert_allclose(rotated_light, rotated_object, rtol=1e-5, atol=1e-5)
    # And on the GPU: each configuration's image agrees with that same per-vertex shading.
    for got, vis in ((got_obj, vis_obj), (got_light, vis_light)):
        want = rotated_object[vis]
        assert np.median(np.abs(got - want) / (want + 0.05)) < 0.02


def test_corner_domain_flat_faces(bpy_module, lit_scene):
    """A flat-shaded cube baked per corner: every face is uniform and equals shade() there."""
    import bmesh
    import prt_addon.api as api

    mesh = bpy_module.data.meshes.new("Cube")
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=2.0)
    bm.to_mesh(mesh)
    bm.free()
    obj = bpy_module.data.objects.new("Cube", mesh)
    lit_scene.collection.objects.link(obj)
    obj.rotation_euler = (0.0, 0.0, math.radians(35))
    order = 3
    loop_poly = np.repeat(np.arange(len(mesh.polygons)), [p.loop_total for p in mesh.polygons])
    fn = np.empty(len(mesh.polygons) * 3, dtype=np.float32)
    mesh.polygons.foreach_get("normal", fn)
    write_bake(obj, clamped_cosine_rows(fn.reshape(-1, 3)[loop_poly], order), order, "CORNER")
    set_light(lit_scene, sun_sky_light(order))
    lit_scene.prt_display.albedo_source = "WHITE"
    values = api.shade(obj, lit_scene)
    assert values.shape == (len(mesh.loops), 3)
    image = api.render_view(lit_scene, 256, 256)
    # Camera along +Y: the faces with world normals -X rotated (35 deg) and -Y rotated are seen.
    mw = np.array(obj.matrix_world)
    depsgraph = bpy_module.context.evaluated_depsgraph_get()
    cam = lit_scene.camera
    vp = np.array(cam.calc_matrix_camera(depsgraph, x=256, y=256)) @ np.array(cam.matrix_world.inverted())
    seen = 0
    for poly in mesh.polygons:
        n_world = mw[:3, :3] @ np.array(poly.normal)
        if n_world[1] > -0.3:
            continue
        centre = mw @ np.r_[np.array(poly.center), 1.0]
        clip = vp @ centre
        col = int((clip[0] / clip[3] + 1) * 128)
        row = int((1 - clip[1] / clip[3]) * 128)
        np.testing.assert_allclose(image[row, col, :3], values[poly.loop_start], rtol=1e-4)
        seen += 1
    assert seen == 2


def _pixel_of(bpy, scene, point, size):
    """(row, col) of a world point in a size x size render of the scene camera."""
    cam = scene.camera
    depsgraph = bpy.context.evaluated_depsgraph_get()
    vp = np.array(cam.calc_matrix_camera(depsgraph, x=size, y=size)) @ np.array(cam.matrix_world.inverted())
    clip = vp @ np.r_[point, 1.0]
    return (1.0 - clip[1] / clip[3]) * 0.5 * size, (clip[0] / clip[3] + 1.0) * 0.5 * size


def _evaluated_centre(bpy, obj):
    """World-space mean of the vertices Blender evaluates for obj (modifiers, shape keys)."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    mesh = obj.evaluated_get(depsgraph).data
    mw = np.array(obj.matrix_world)
    return mw[:3, :3] @ local_positions(mesh).mean(axis=0) + mw[:3, 3]


def test_deformed_objects_are_drawn_as_the_viewport_shows_them(bpy_module, lit_scene):
    """Shape keys and modifiers that move vertices but keep the topology (the bake uses the same
    evaluated mesh): the overlay covers the evaluated mesh, follows a changed shape-key value
    without a stale cache, and a second object sharing the mesh keeps its own deformation."""
    bpy = bpy_module
    size = 128
    set_light(lit_scene, sun_sky_light(3))
    lit_scene.prt_display.albedo_source = "WHITE"
    obj = bake_sphere(bpy, 3, radius=0.5, segments=24, rings=12)
    obj.location = (-1.2, 0.0, 0.0)
    twin = bpy.data.objects.new("Twin", obj.data)  # same mesh, no modifier
    lit_scene.collection.objects.link(twin)
    twin.location = (1.2, 0.0, 0.0)
    obj.shape_key_add(name="Basis")
    up = obj.shape_key_add(name="Up")
    co = local_positions(obj.data)
    co[:, 2] += 1.0
    up.data.foreach_set("co", co.astype(np.float32).ravel())

    def coverage_centres():
        bpy.context.view_layer.update()
        alpha = api.render_view(lit_scene, size, size)[..., 3] > 0
        out = []
        for half in (slice(0, size // 2), slice(size // 2, size)):  # obj on the left, twin right
            rows, cols = np.nonzero(alpha[:, half])
            out.append((rows.mean(), cols.mean() + half.start))
        return out

    import prt_addon.api as api

    for value, strength in ((0.0, 0.0), (1.0, 0.0), (0.3, 0.0), (0.3, 0.8)):
        up.value = value
        if strength:
            displace = obj.modifiers.new("Displace", "DISPLACE")
            displace.direction = "Z"
            displace.strength = strength
        centres = coverage_centres()
        for target, (row, col) in zip((obj, twin), centres):
            want_row, want_col = _pixel_of(bpy, lit_scene, _evaluated_centre(bpy, target), size)
            assert abs(row - want_row) < 1.0 and abs(col - want_col) < 1.0, (target.name, value, strength)
    # The last case moved obj (shape key + modifier) and not twin (shape key only): different.
    assert _evaluated_centre(bpy, obj)[2] - _evaluated_centre(bpy, twin)[2] > 0.3
    _row, _col = _pixel_of(bpy, lit_scene, np.array([-1.2, 0.0, 0.3]), size)
    assert abs(centres[0][0] - _row) > 5.0  # the undeformed-plus-shape-key position is not drawn


def test_modifier_that_reorders_vertices_draws_the_undeformed_mesh(bpy_module, lit_scene):
    """A Geometry Nodes Sort Elements modifier keeps every count but renumbers the vertices: the
    baked per-vertex transfer no longer belongs to the evaluated vertex i, so the display draws
    the mesh as baked (same image as without the modifier), not the evaluated positions on the
    original triangles."""
    import prt_addon.api as api

    bpy = bpy_module
    set_light(lit_scene, sun_sky_light(3))
    lit_scene.prt_display.albedo_source = "WHITE"
    obj = bake_sphere(bpy, 3, segments=24, rings=12)
    plain = api.render_view(lit_scene, 96, 96)

    tree = bpy.data.node_groups.new("Sort", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    group_in, group_out = tree.nodes.new("NodeGroupInput"), tree.nodes.new("NodeGroupOutput")
    sort = tree.nodes.new("GeometryNodeSortElements")  # points, by the key below
    position = tree.nodes.new("GeometryNodeInputPosition")
    separate = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(position.outputs[0], separate.inputs[0])
    tree.links.new(separate.outputs["X"], sort.inputs["Sort Weight"])
    tree.links.new(group_in.outputs[0], sort.inputs["Geometry"])
    tree.links.new(sort.outputs["Geometry"], group_out.inputs[0])
    obj.modifiers.new("Sort", "NODES").node_group = tree
    bpy.context.view_layer.update()
    evaluated = local_positions(obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data)
    assert not np.array_equal(evaluated, local_positions(obj.data))  # really renumbered
    assert len(evaluated) == len(obj.data.vertices)

    sorted_view = api.render_view(lit_scene, 96, 96)
    np.testing.assert_array_equal(sorted_view, plain)


def test_world_projection_seam(bpy_module, lit_scene):
    """With no override the display reads world_projection.current_world_coeffs: a constant
    colour world c lights an unshadowed sphere to radiance c everywhere (white furnace)."""
    from prt_addon.blender.world import projection as world_projection
    import prt_addon.api as api
    from prt_addon.blender.display import lighting

    world = bpy_module.data.worlds.new("Const")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.3, 0.5, 0.7, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
    lit_scene.world = world
    lighting.set_light_override(lit_scene, None)
    world_projection.project_and_store(lit_scene, 3)
    obj = bake_sphere(bpy_module, 3, segments=16, rings=8)
    np.testing.assert_allclose(
        api.shade(obj, lit_scene), np.tile([0.3, 0.5, 0.7], (len(obj.data.vertices), 1)), rtol=1e-3
    )


def test_handler_removed_on_unregister_and_file_load(bpy_module, addon, gpu_ready, tmp_path):
    import prt_addon
    from prt_addon.blender.display import handlers
    from prt_addon.blender.display import draw as display_draw

    def removable(handle):
        try:
            bpy_module.types.SpaceView3D.draw_handler_remove(handle, "WINDOW")
        except ValueError:
            return False
        return True

    handle = display_draw.draw_handle()
    assert handle is not None
    prt_addon.unregister()
    assert display_draw.draw_handle() is None
    assert not removable(handle)  # Blender no longer knows the callback
    for name in ("load_pre", "load_post", "depsgraph_update_post"):
        assert not any(
            getattr(f, "__module__", "") == handlers.__name__ for f in getattr(bpy_module.app.handlers, name)
        )

    prt_addon.register()
    first = display_draw.draw_handle()
    assert first is not None
    path = str(tmp_path / "empty.blend")
    bpy_module.ops.wm.save_as_mainfile(filepath=path)
    bpy_module.ops.wm.open_mainfile(filepath=path)
    second = display_draw.draw_handle()
    assert second is not None and second is not first
    assert not removable(first)  # removed before the file loaded
    # Exactly one live handler: the new one (removing it here, then restoring it).
    assert removable(second)
    display_draw._draw_handle = None
    display_draw.add_draw_handler()


def test_save_reload_displays_from_stored_attributes(bpy_module, lit_scene, tmp_path):
    import prt_addon.api as api
    from prt_addon.blender.display import gpu_cache
    from prt_addon.blender.world import nodes as world_nodes

    order = 8  # texture path; the attributes path is covered by the other tests
    obj = bake_sphere(bpy_module, order, segments=32, rings=16)
    obj.rotation_euler = (0.2, 0.5, -0.3)
    light = sun_sky_light(order)
    set_light(lit_scene, light)
    bpy_module.ops.prt.set_light_rotation(rotation=(0.0, 0.0, 1.0))
    lit_scene.prt_display.albedo_source = "WHITE"
    before = api.render_view(lit_scene, 128, 128)
    shade_before = api.shade(obj, lit_scene)
    path = str(tmp_path / "baked.blend")
    bpy_module.ops.wm.save_as_mainfile(filepath=path)

    bpy_module.ops.wm.read_factory_settings(use_empty=True)
    assert gpu_cache._mesh_cache == {}
    bpy_module.ops.wm.open_mainfile(filepath=path)
    scene = bpy_module.context.scene
    assert gpu_cache._mesh_cache == {}  # nothing carried over: the display reads the file's data
    assert world_nodes.mapping_rotation_euler(scene.world)[2] == pytest.approx(1.0)
    set_light(scene, light)  # the injected light is not saved (a projected world is)
    obj = bpy_module.data.objects["Sphere"]
    np.testing.assert_allclose(api.shade(obj, scene), shade_before, rtol=1e-6, atol=1e-7)
    after = api.render_view(scene, 128, 128)
    assert (after[..., 3] > 0).sum() > 1000
    np.testing.assert_allclose(after, before, rtol=1e-5, atol=1e-6)


def test_save_png_uses_scene_colour_management(bpy_module, lit_scene, tmp_path):
    """Standard view transform: the PNG holds the sRGB encoding of the linear value."""
    import prt_addon.api as api

    lit_scene.view_settings.view_transform = "Standard"
    lit_scene.view_settings.exposure = 0.0
    lit_scene.view_settings.gamma = 1.0
    lit_scene.view_settings.look = "None"
    linear = np.array([0.0, 0.05, 0.18, 0.5, 1.0])
    image = np.zeros((4, 5, 4), dtype=np.float32)
    image[..., :3] = linear[None, :, None]
    image[..., 3] = 1.0
    path = str(tmp_path / "ramp.png")
    api.save_png(image, path, lit_scene)
    loaded = bpy_module.data.images.load(path)
    loaded.colorspace_settings.name = "Non-Color"  # read the stored bytes, not decoded
    px = np.empty(4 * 5 * 4, dtype=np.float32)
    loaded.pixels.foreach_get(px)
    stored = px.reshape(4, 5, 4)[0, :, 0]
    srgb = np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * linear ** (1 / 2.4) - 0.055)
    np.testing.assert_allclose(stored, srgb, atol=1.0 / 255 + 1e-6)


def test_texture_path_with_several_materials(bpy_module, lit_scene):
    """Per-material index buffers of the second slot start at a high vertex index (Blender may
    store them as 16-bit indices plus a base vertex): gl_VertexID must still be the element."""
    import prt_addon.api as api

    order = 8
    obj = bake_sphere(bpy_module, order, segments=64, rings=32)
    obj.rotation_euler = (0.1, 0.2, 0.3)
    colours = [(1.0, 1.0, 1.0, 1.0), (0.5, 0.5, 0.5, 1.0)]
    for i, colour in enumerate(colours):
        mat = bpy_module.data.materials.new(f"M{i}")
        mat.diffuse_color = colour
        if mat.node_tree is not None:
            mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = colour
        obj.data.materials.append(mat)
    centres = np.empty(len(obj.data.polygons) * 3, dtype=np.float32)
    obj.data.polygons.foreach_get("center", centres)
    upper = (centres.reshape(-1, 3)[:, 2] > 0.0).astype(np.int32)
    obj.data.polygons.foreach_set("material_index", 1 - upper)  # slot 1 = lower half
    obj.data.update()
    set_light(lit_scene, sun_sky_light(order))
    lit_scene.prt_display.albedo_source = "MATERIAL"
    image = api.render_view(lit_scene, 512, 512)
    expected = api.shade(obj, lit_scene)
    z = local_positions(obj.data)[:, 2]
    got, visible = sample_at_vertices(bpy_module, obj, lit_scene, image)
    zv = z[visible]
    keep = np.abs(zv) > 0.1  # away from the seam between the two materials
    tint = np.where(zv[keep] > 0, 1.0, 0.5)[:, None]
    want = expected[visible][keep] * tint
    err = np.abs(got[keep] - want) / (want + 0.05)
    assert (zv[keep] < 0).sum() > 50 and (zv[keep] > 0).sum() > 50
    assert np.median(err) < 0.01 and err.max() < 0.05, (np.median(err), err.max())


def test_viewport_callback_draws_with_exposure_and_toggle(bpy_module, lit_scene, monkeypatch):
    """The draw-handler callback itself, run inside an offscreen with a stand-in for the 3D
    View's context: it draws what render_view(display=True) draws (2**exposure, the view
    transform; the last step, colour.encode_display, is Blender's merge of the overlay), and nothing when the sidebar
    toggle is off."""
    import types

    import gpu
    import mathutils
    import prt_addon.api as api
    from prt_addon.blender.display import colour, offscreen
    from prt_addon.blender.display import draw as display_draw

    bake_sphere(bpy_module, 4, segments=32, rings=16)
    set_light(lit_scene, sun_sky_light(4))
    lit_scene.prt_display.albedo_source = "WHITE"
    lit_scene.view_settings.exposure = 0.0
    unexposed = api.render_view(lit_scene, 128, 128, display=True)
    lit_scene.view_settings.exposure = 1.0
    reference = api.render_view(lit_scene, 128, 128, display=True)
    view, proj = offscreen.camera_matrices(lit_scene, 128, 128)
    context = types.SimpleNamespace(
        scene=lit_scene,
        region_data=types.SimpleNamespace(perspective_matrix=mathutils.Matrix((proj @ view).tolist())),
        view_layer=bpy_module.context.view_layer,
        space_data=None,
        evaluated_depsgraph_get=bpy_module.context.evaluated_depsgraph_get,
    )
    monkeypatch.setattr(display_draw, "bpy", types.SimpleNamespace(context=context, types=bpy_module.types))

    def viewport_frame():
        off = gpu.types.GPUOffScreen(128, 128, format="RGBA32F")
        with off.bind():
            fb = gpu.state.active_framebuffer_get()
            fb.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
            display_draw._draw_callback()
            img = np.asarray(fb.read_color(0, 0, 128, 128, 4, 0, "FLOAT")).T.reshape(128, 128, 4)[::-1].copy()
        off.free()
        return img

    frame = viewport_frame()
    mask = reference[..., 3] > 0
    assert mask.sum() > 1000
    np.testing.assert_allclose(colour.encode_display(frame[mask, :3]), reference[mask, :3], rtol=1e-5, atol=1e-6)
    assert np.all(reference[mask, :3] >= unexposed[mask, :3]) and np.mean(reference - unexposed) > 0.01
    lit_scene.prt.show_display = False
    assert np.all(viewport_frame() == 0.0)
