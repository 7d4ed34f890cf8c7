"""Live PRT display over a session: deformed meshes, the draw callback, handler cleanup, save/reload, PNGs.

Needs the GPU initialised headless; helpers come from tests/helpers/display_scenes.py, the lit_scene fixture from tests/helpers/fixtures_display.py.
"""

import numpy as np
import pytest
from helpers.display_scenes import bake_sphere, local_positions, set_light, sun_sky_light


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


def test_handler_removed_on_unregister_and_file_load(bpy_module, addon, gpu_ready, tmp_path):
    import prt_addon
    from prt_addon.blender.display import draw as display_draw, handlers

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
    assert second is not None
    assert second is not first
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


def test_viewport_callback_draws_with_exposure_and_toggle(bpy_module, lit_scene, monkeypatch):
    """The draw-handler callback itself, run inside an offscreen with a stand-in for the 3D
    View's context: it draws what render_view(display=True) draws (2**exposure, the view
    transform; the last step, colour.encode_display, is Blender's merge of the overlay), and nothing when the sidebar
    toggle is off."""
    import types

    import gpu
    import mathutils

    import prt_addon.api as api
    from prt_addon.blender.display import colour, draw as display_draw, offscreen

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

    def viewport_frame():
        off = gpu.types.GPUOffScreen(128, 128, format="RGBA32F")
        with off.bind():
            fb = gpu.state.active_framebuffer_get()
            fb.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
            display_draw.draw_viewport(context)
            img = np.asarray(fb.read_color(0, 0, 128, 128, 4, 0, "FLOAT")).T.reshape(128, 128, 4)[::-1].copy()
        off.free()
        return img

    frame = viewport_frame()
    mask = reference[..., 3] > 0
    assert mask.sum() > 1000
    np.testing.assert_allclose(colour.encode_display(frame[mask, :3]), reference[mask, :3], rtol=1e-5, atol=1e-6)
    assert np.all(reference[mask, :3] >= unexposed[mask, :3])
    assert np.mean(reference - unexposed) > 0.01
    lit_scene.prt.show_display = False
    assert np.all(viewport_frame() == 0.0)
