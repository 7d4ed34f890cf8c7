"""Bad input, as a user would give it: every case ends in a clear message in Blender's
report and leaves the .blend exactly as it was.

Operators run through bpy.ops. In background mode an operator that reports ERROR and returns
CANCELLED makes bpy.ops raise RuntimeError("Error: <message>"), and a failed poll raises
RuntimeError("Operator bpy.ops.<id>.poll() <poll message>"): the tests assert on that text.
The Python API raises ValueError with the same kind of message. The modal bake is driven with a
stand-in for the operator instance, as in tests/test_bake.py.

"Exactly as it was" is checked with a snapshot of everything a .blend would save that the
add-on could touch: every mesh's attributes (names, domains, types, values) and ID properties,
every object's transform, selection and visibility, the active object, the scene's ID properties
(scene.prt, prt_world, prt_bake and the stored SH), the world's node tree, and the ID counts.
"""

import json
import types

import numpy as np
import pytest

from conftest import ModalStandIn, bundled_hdri_path, fake_event

pytestmark = pytest.mark.blender


# --- snapshot ---------------------------------------------------------------------------------


def _idprops(owner):
    out = {}
    for key in owner.keys():
        value = owner[key]
        if hasattr(value, "to_dict"):
            value = value.to_dict()
        elif hasattr(value, "to_list"):
            value = value.to_list()
        out[key] = value
    return json.dumps(out, sort_keys=True, default=repr)


def _attribute_values(attr):
    key = {
        "FLOAT_COLOR": "color",
        "BYTE_COLOR": "color",
        "FLOAT_VECTOR": "vector",
        "FLOAT": "value",
        "INT": "value",
        "BOOLEAN": "value",
    }.get(attr.data_type)
    if key is None or len(attr.data) == 0:
        return None
    width = {"color": 4, "vector": 3, "value": 1}[key]
    dtype = {"INT": np.int32, "BOOLEAN": bool}.get(attr.data_type, np.float32)
    buf = np.empty(len(attr.data) * width, dtype)
    attr.data.foreach_get(key, buf)
    return buf.tobytes()


def _socket_value(socket):
    value = getattr(socket, "default_value", None)
    try:
        return tuple(value)
    except TypeError:
        return value


def snapshot(bpy):
    """Everything the add-on could change in a .blend, as comparable plain data."""
    snap = {}
    for mesh in bpy.data.meshes:
        attrs = []
        for attr in mesh.attributes:
            attrs.append((attr.name, attr.domain, attr.data_type, _attribute_values(mesh.attributes[attr.name])))
        snap[f"mesh:{mesh.name}:{mesh.library}"] = (
            sorted(attrs, key=lambda a: a[0]),
            _idprops(mesh),
            mesh.color_attributes.active_color_name,
        )
    for obj in bpy.data.objects:
        snap[f"object:{obj.name}:{obj.library}"] = (
            tuple(tuple(row) for row in obj.matrix_world),
            obj.select_get(),
            obj.hide_get(),
            obj.hide_viewport,
            obj.data.name if obj.data else None,
            obj.mode,
            _idprops(obj),
        )
    view_layer = bpy.context.view_layer
    snap["active"] = view_layer.objects.active.name if view_layer.objects.active else None
    for scene in bpy.data.scenes:
        snap[f"scene:{scene.name}"] = (_idprops(scene), scene.world.name if scene.world else None)
    for world in bpy.data.worlds:
        tree = world.node_tree
        nodes = []
        if tree is not None:
            for node in tree.nodes:
                nodes.append(
                    (
                        node.name,
                        node.bl_idname,
                        node.mute,
                        getattr(getattr(node, "image", None), "name", None),
                        tuple((s.identifier, _socket_value(s)) for s in node.inputs),
                    )
                )
            links = sorted(
                (l.from_node.name, l.from_socket.identifier, l.to_node.name, l.to_socket.identifier) for l in tree.links
            )
        else:
            links = []
        snap[f"world:{world.name}"] = (sorted(nodes, key=repr), links, tuple(world.color), _idprops(world))
    for image in bpy.data.images:
        snap[f"image:{image.name}"] = (image.filepath, image.source, tuple(image.size))
    snap["counts"] = {
        name: len(getattr(bpy.data, name))
        for name in (
            "objects",
            "meshes",
            "images",
            "worlds",
            "materials",
            "node_groups",
            "scenes",
            "libraries",
            "curves",
            "collections",
        )
    }
    return snap


def assert_unchanged(before, after):
    # repr: NaN compares unequal to itself but prints the same.
    changed = sorted(k for k in set(before) | set(after) if repr(before.get(k)) != repr(after.get(k)))
    assert not changed, f"the .blend changed: {changed}"


def refused(bpy, call, match):
    """Run call(), which must fail with a message matching `match`; the .blend must not change.
    Returns the message."""
    before = snapshot(bpy)
    with pytest.raises((RuntimeError, ValueError)) as info:
        call()
    message = str(info.value)
    assert __import__("re").search(match, message), message
    assert_unchanged(before, snapshot(bpy))
    return message


# --- scene helpers ----------------------------------------------------------------------------


@pytest.fixture(autouse=True)
def _no_bake_left_running(addon):
    yield
    from prt_addon.blender.bake import runner as bake_runner

    for op in list(bake_runner._running):
        op._bake.cancel()
        op._steps.close()
    bake_runner._running.clear()


@pytest.fixture
def scene(empty_scene, bpy_module):
    """A sphere on a ground plane, both baked, a world with an HDRI projected; nothing selected."""
    bpy = bpy_module
    bpy.ops.mesh.primitive_plane_add(size=6)
    ground = bpy.context.object
    ground.name = "Ground"
    bpy.ops.mesh.primitive_uv_sphere_add(segments=16, ring_count=8, location=(0, 0, 1))
    sphere = bpy.context.object
    sphere.name = "Sphere"
    sphere.data.shade_smooth()
    world = bpy.data.worlds.new("World")
    if world.node_tree is None:  # Blender 4.x: new worlds have no nodes
        world.use_nodes = True
    empty_scene.world = world
    env = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(bundled_hdri_path("forest"), check_existing=True)
    world.node_tree.links.new(env.outputs["Color"], world.node_tree.nodes["Background"].inputs["Color"])
    empty_scene.prt_world.order = 4
    assert bpy.ops.prt.project_world() == {"FINISHED"}
    settings = empty_scene.prt_bake
    settings.order, settings.samples = 3, 32
    for obj in (ground, sphere):
        obj.select_set(True)
    assert bpy.ops.prt.bake_transfer() == {"FINISHED"}
    bpy.ops.object.select_all(action="DESELECT")
    bpy.context.view_layer.objects.active = None
    return types.SimpleNamespace(scene=empty_scene, ground=ground, sphere=sphere, world=world, env=env)


def select_only(bpy, *objects):
    bpy.ops.object.select_all(action="DESELECT")
    for obj in objects:
        obj.select_set(True)
    bpy.context.view_layer.objects.active = objects[0] if objects else None


def bake(bpy):
    return bpy.ops.prt.bake_transfer()


def new_object(bpy, scene, name, data):
    obj = bpy.data.objects.new(name, data)
    scene.collection.objects.link(obj)
    return obj


# --- bake: what is selected -------------------------------------------------------------------


def test_nothing_selected(bpy_module, scene):
    refused(bpy_module, lambda: bake(bpy_module), r"nothing selected: select the mesh objects")


def test_empty_selected(bpy_module, scene):
    empty = new_object(bpy_module, scene.scene, "Empty", None)
    select_only(bpy_module, empty)
    refused(bpy_module, lambda: bake(bpy_module), r"'Empty' is a empty, not a mesh: convert it")


def test_curve_selected(bpy_module, scene):
    bpy = bpy_module
    curve = bpy.data.curves.new("Curve", "CURVE")
    spline = curve.splines.new("BEZIER")
    spline.bezier_points.add(1)
    obj = new_object(bpy, scene.scene, "Curve", curve)
    select_only(bpy, obj)
    refused(bpy, lambda: bake(bpy), r"'Curve' is a curve, not a mesh: convert it \(Object > Convert > Mesh\)")


def test_text_selected(bpy_module, scene):
    bpy = bpy_module
    obj = new_object(bpy, scene.scene, "Text", bpy.data.curves.new("Text", "FONT"))
    select_only(bpy, obj)
    refused(bpy, lambda: bake(bpy), r"'Text' is a font, not a mesh")


def test_mesh_without_faces(bpy_module, scene):
    bpy = bpy_module
    mesh = bpy.data.meshes.new("Wire")
    mesh.from_pydata([(0, 0, 3), (1, 0, 3), (1, 1, 3)], [(0, 1), (1, 2)], [])
    select_only(bpy, new_object(bpy, scene.scene, "Wire", mesh))
    refused(bpy, lambda: bake(bpy), r"'Wire' has no faces: a transfer bake needs faces")


def test_empty_mesh(bpy_module, scene):
    bpy = bpy_module
    select_only(bpy, new_object(bpy, scene.scene, "Nothing", bpy.data.meshes.new("Nothing")))
    refused(bpy, lambda: bake(bpy), r"'Nothing' has no faces")


def test_nan_coordinates(bpy_module, scene):
    """NaN vertices: refused for the selected object, and not an occluder for the others."""
    bpy = bpy_module
    mesh = bpy.data.meshes.new("Broken")
    mesh.from_pydata([(0, 0, 3), (1, 0, 3), (0, 1, 3), (float("nan"), 0, 4)], [], [(0, 1, 2), (0, 1, 3)])
    broken = new_object(bpy, scene.scene, "Broken", mesh)
    select_only(bpy, broken)
    refused(bpy, lambda: bake(bpy), r"'Broken' has 1 vertices with non-finite coordinates \(NaN or infinity\)")
    # With it in the scene, the other objects still bake (its finite triangle still occludes).
    select_only(bpy, scene.sphere)
    assert bake(bpy) == {"FINISHED"}
    from prt_addon import api

    assert np.isfinite(api.shade(scene.sphere)).all()


def test_nan_location(bpy_module, scene):
    bpy = bpy_module
    bpy.ops.mesh.primitive_cube_add(location=(0, 5, 1))
    cube = bpy.context.object
    cube.location.x = float("nan")  # Blender refuses inf here, but takes NaN
    select_only(bpy, cube)
    refused(bpy, lambda: bake(bpy), r"'Cube' has a non-finite transform \(NaN or infinity")


def test_zero_size_mesh(bpy_module, scene):
    bpy = bpy_module
    mesh = bpy.data.meshes.new("Point")
    mesh.from_pydata([(0, 0, 3)] * 3, [], [(0, 1, 2)])
    select_only(bpy, new_object(bpy, scene.scene, "Point", mesh))
    refused(bpy, lambda: bake(bpy), r"'Point' has zero size")


def test_zero_scale(bpy_module, scene):
    bpy = bpy_module
    bpy.ops.mesh.primitive_cube_add(location=(0, 5, 1), scale=(0, 0, 0))
    select_only(bpy, bpy.context.object)
    refused(bpy, lambda: bake(bpy), r"has zero size")


def test_linked_library_mesh(bpy_module, scene, tmp_path):
    """A mesh object linked from another .blend cannot be written: refused, make it local."""
    bpy = bpy_module
    library = str(tmp_path / "library.blend")
    mesh = bpy.data.meshes.new("LibMesh")
    mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
    lib_obj = bpy.data.objects.new("LibObject", mesh)
    bpy.data.libraries.write(library, {lib_obj}, fake_user=True)
    bpy.data.objects.remove(lib_obj)
    bpy.data.meshes.remove(mesh)
    with bpy.data.libraries.load(library, link=True) as (data_from, data_to):
        data_to.objects = ["LibObject"]
    linked = data_to.objects[0]
    scene.scene.collection.objects.link(linked)
    assert linked.library is not None
    select_only(bpy, linked)
    refused(bpy, lambda: bake(bpy), r"'LibObject' is linked from a library and cannot be written: make it local")


def test_topology_modifier(bpy_module, scene):
    bpy = bpy_module
    bpy.ops.mesh.primitive_cube_add(location=(0, 5, 1))
    cube = bpy.context.object
    cube.modifiers.new("Subdivision", "SUBSURF")
    select_only(bpy, cube)
    refused(bpy, lambda: bake(bpy), r"modifiers that change its topology \[Subdivision.*Apply")


def test_edit_mode(bpy_module, scene):
    bpy = bpy_module
    select_only(bpy, scene.sphere)
    bpy.ops.object.mode_set(mode="EDIT")
    try:
        refused(bpy, lambda: bake(bpy), r"poll\(\) Switch to Object Mode to bake")
    finally:
        bpy.ops.object.mode_set(mode="OBJECT")


# --- bake: settings ---------------------------------------------------------------------------


@pytest.mark.parametrize("order", [0, 1000])
def test_bake_order_out_of_range(bpy_module, scene, order):
    from prt_addon import api

    refused(
        bpy_module,
        lambda: api.bake([scene.sphere], order=order),
        rf"order must be an integer from 1 to 16, got {order}",
    )
    # The sidebar cannot even hold such a value: Blender clamps it to the property's range.
    scene.scene.prt_bake.order = order
    assert 1 <= scene.scene.prt_bake.order <= 16


def test_zero_samples(bpy_module, scene):
    from prt_addon import api

    refused(bpy_module, lambda: api.bake([scene.sphere], samples=0), r"samples must be an integer >= 2, got 0")


def test_embree_requested_where_missing(bpy_module, scene, monkeypatch):
    from prt_addon.core import raytrace

    monkeypatch.setattr(raytrace, "EMBREE_AVAILABLE", False)
    monkeypatch.setattr(raytrace, "EMBREE_IMPORT_ERROR", "ImportError: No module named 'embreex'")
    scene.scene.prt_bake.backend = "EMBREE"
    before = snapshot(bpy_module)
    scene.scene.prt_bake.backend = "EMBREE"
    select_only(bpy_module, scene.sphere)
    before = snapshot(bpy_module)
    with pytest.raises(RuntimeError, match=r"the Embree backend is not available on this system .*choose Auto"):
        bake(bpy_module)
    assert_unchanged(before, snapshot(bpy_module))


# --- bake: while running ----------------------------------------------------------------------


def _timer_event():
    return fake_event("TIMER", "NOTHING")  # (made when used: conftest's fake_event imports bpy)


def _start_modal(bpy, scene_ns, monkeypatch):
    from prt_addon.blender.bake import job as bake_job
    from prt_addon.blender.bake import settings as bake_settings
    from prt_addon.blender.bake import runner as bake_runner
    from prt_addon.blender.ops import bake as bake_op

    monkeypatch.setattr(bake_runner, "TIME_SLICE", 0.0)
    monkeypatch.setattr(bake_runner, "TIMER_GAP", 0.0)
    job = bake_job.BakeJob(
        [scene_ns.sphere, scene_ns.ground], bake_settings.BakeSettings(order=4, samples=256, chunk_rays=2048)
    )
    op = ModalStandIn(bake_op, job)
    bake_runner._running.add(op)  # what invoke() does
    assert op.modal(bpy.context, _timer_event()) == {"RUNNING_MODAL"}
    assert 0 < job.fraction < 1
    return bake_runner, op


def test_invoke_failing_after_the_job_starts_stops_it(bpy_module, scene, monkeypatch):
    """invoke() creates the job (whose first slices start tracing at once), then adds the timer
    and the modal handler: if that fails, the job's threads are stopped and nothing is kept."""
    from prt_addon.blender.bake import job as bake_job
    from prt_addon.blender.bake import settings as bake_settings
    from prt_addon.blender.ops import bake as bake_op
    from prt_addon.blender.bake import runner as bake_runner

    bpy = bpy_module

    class WithWindow:  # bpy as seen by bake_ops, but not in background mode
        app = types.SimpleNamespace(background=False)

        def __getattr__(self, name):
            return getattr(bpy, name)

    class WindowManager:
        def event_timer_add(self, *args, **kwargs):
            raise RuntimeError("no timer")

        def progress_end(self):
            pass

    class Operator:
        pass

    monkeypatch.setattr(bake_runner, "bpy", WithWindow())
    job = bake_job.BakeJob(
        [scene.sphere, scene.ground], bake_settings.BakeSettings(order=4, samples=256, chunk_rays=2048)
    )
    assert job.plans[0].computation._pending, "the first object's slices should be queued"
    op = Operator()
    cls = bake_op.PRT_OT_bake_transfer
    op._job = lambda context: job
    op._cleanup = lambda context: cls._cleanup(op, context)
    context = types.SimpleNamespace(window=object(), window_manager=WindowManager(), workspace=None, screen=None)
    before = snapshot(bpy)
    with pytest.raises(RuntimeError, match="no timer"):
        cls.invoke(op, context, None)
    assert op not in bake_runner._running
    assert job._pool._shutdown and all(not t.is_alive() for t in job._pool._threads)
    assert_unchanged(before, snapshot(bpy))


def test_bake_while_another_bake_runs(bpy_module, scene, monkeypatch):
    from prt_addon.blender.bake import runner as bake_runner

    bpy = bpy_module
    before = snapshot(bpy)
    bake_ops, op = _start_modal(bpy, scene, monkeypatch)
    try:
        select_only(bpy, scene.sphere)
        before = snapshot(bpy)
        refused(bpy, lambda: bake(bpy), r"a bake is already running: wait for it to finish, or press Esc")
        assert_unchanged(before, snapshot(bpy))
    finally:
        assert op.modal(bpy.context, fake_event("ESC")) == {"CANCELLED"}
    assert not bake_runner._running
    assert ({"WARNING"}, "PRT: bake cancelled, nothing was changed") in op.reports


def test_topology_change_during_modal_bake(bpy_module, scene, monkeypatch):
    from prt_addon.blender.bake import runner as bake_runner
    import bmesh

    bpy = bpy_module
    bake_ops, op = _start_modal(bpy, scene, monkeypatch)
    # The user edits the sphere while the bake runs: the bake must refuse to write.
    bm = bmesh.new()
    bm.from_mesh(scene.sphere.data)
    bm.verts.ensure_lookup_table()
    bmesh.ops.delete(bm, geom=[bm.verts[0]], context="VERTS")
    bm.to_mesh(scene.sphere.data)
    bm.free()
    before = snapshot(bpy)
    result = {"RUNNING_MODAL"}
    while result == {"RUNNING_MODAL"}:
        result = op.modal(bpy.context, _timer_event())
    assert result == {"CANCELLED"}
    assert any(
        "ERROR" in kind and "topology of 'Sphere' changed during the bake: bake again" in msg
        for kind, msg in op.reports
    ), op.reports
    assert_unchanged(before, snapshot(bpy))
    assert not bake_runner._running


def test_unregister_in_the_middle_of_a_modal_bake(bpy_module, scene, monkeypatch):
    from prt_addon.blender.bake import job as bake_job
    from prt_addon.blender.bake import runner as bake_runner
    from prt_addon.blender.bake import settings as bake_settings

    bpy = bpy_module
    import prt_addon

    wm = bpy.context.window_manager
    bake_ops, op = _start_modal(bpy, scene, monkeypatch)
    op._timer = wm.event_timer_add(0.02)  # a real window-manager timer, as invoke() adds
    # Another bake invoked but not stepped yet: closing its unstarted steps() generator runs none
    # of the generator's clean-up, so unregister must close the job itself.
    pending_job = bake_job.BakeJob([scene.ground], bake_settings.BakeSettings(order=2, samples=16))
    from prt_addon.blender.ops import bake as bake_op

    bake_runner._running.add(ModalStandIn(bake_op, pending_job))
    before = snapshot(bpy)
    job = op._bake
    prt_addon.unregister()  # the user disables the add-on while it bakes
    try:
        assert op._timer is None, "the bake's timer was not removed"
        assert not bake_runner._running and job._cancel
        assert job._pool._shutdown, "the bake's worker threads were not stopped"
        assert pending_job._cancel
        assert pending_job._pool._shutdown, "the pending bake's worker threads were not stopped"
        # If Blender still delivers an event to the dead operator, it writes nothing.
        assert op.modal(bpy.context, _timer_event()) == {"CANCELLED"}
    finally:
        prt_addon.register()
    after = snapshot(bpy)
    assert_unchanged(before, after)
    # Registered again, everything works.
    select_only(bpy, scene.sphere)
    assert bake(bpy) == {"FINISHED"}


# --- world ------------------------------------------------------------------------------------


def project(bpy):
    return bpy.ops.prt.project_world()


def test_no_world(bpy_module, scene):
    scene.scene.world = None
    refused(bpy_module, lambda: project(bpy_module), r"Scene 'Scene' has no World: add one in the World properties")


def test_world_image_file_missing(bpy_module, scene, tmp_path):
    bpy = bpy_module
    image = bpy.data.images.new("missing.exr", 4, 2, float_buffer=True)
    image.source = "FILE"
    image.filepath = str(tmp_path / "missing.exr")
    scene.env.image = image
    refused(bpy, lambda: project(bpy), r"Image 'missing.exr' could not be loaded: file '.*missing.exr' not found")


def test_environment_texture_without_image(bpy_module, scene):
    scene.env.image = None
    refused(bpy_module, lambda: project(bpy_module), r"Environment Texture '.*' has no image")


def test_world_output_disconnected(bpy_module, scene):
    tree = scene.world.node_tree
    for link in list(tree.links):
        if link.to_node.bl_idname == "ShaderNodeOutputWorld":
            tree.links.remove(link)
    refused(bpy_module, lambda: project(bpy_module), r"Nothing is connected to the Surface of World 'World'")


def test_negative_strength(bpy_module, scene):
    scene.world.node_tree.nodes["Background"].inputs["Strength"].default_value = -1.0
    refused(bpy_module, lambda: project(bpy_module), r"strength of -1.0: it must be >= 0")


def test_black_world(bpy_module, scene):
    tree = scene.world.node_tree
    background = tree.nodes["Background"]
    tree.links.remove(background.inputs["Color"].links[0])
    background.inputs["Color"].default_value = (0, 0, 0, 1)
    refused(bpy_module, lambda: project(bpy_module), r"emits no light")


def test_nan_world_colour(bpy_module, scene):
    tree = scene.world.node_tree
    background = tree.nodes["Background"]
    tree.links.remove(background.inputs["Color"].links[0])
    background.inputs["Color"].default_value = (float("nan"), 0, 0, 1)
    refused(bpy_module, lambda: project(bpy_module), r"non-finite colour")


@pytest.mark.parametrize("order", [0, 1000])
def test_world_order_out_of_range(bpy_module, scene, order):
    from prt_addon import api

    # order 1000 would need 10^6 coefficients per channel: refused before any work.
    refused(
        bpy_module, lambda: api.project_world(order=order), r"order must be an integer .*got 0|from 1 to 32, got 1000"
    )


def test_rotate_lighting_without_environment_texture(bpy_module, scene):
    tree = scene.world.node_tree
    tree.nodes.remove(scene.env)
    refused(
        bpy_module,
        lambda: bpy_module.ops.prt.set_light_rotation(),
        r"poll\(\) The world has no Environment Texture to rotate",
    )


# --- display ----------------------------------------------------------------------------------


def test_display_with_nothing_baked(bpy_module, scene):
    bpy = bpy_module
    from prt_addon import api

    bpy.ops.mesh.primitive_cube_add(location=(0, 5, 1))
    cube = bpy.context.object
    refused(bpy, lambda: api.shade(cube), r"'Cube': not baked: bake it \(PRT tab > Bake Transfer\)")


def test_display_with_no_projected_world(bpy_module, scene):
    from prt_addon import api

    for key in list(scene.scene.keys()):
        if key.startswith("prt_sh"):
            del scene.scene[key]
    scene.scene.prt_world.stored_order = 0
    refused(bpy_module, lambda: api.shade(scene.sphere), r"no PRT lighting \(project the world first\)")


def test_stale_bake(bpy_module, scene):
    """Topology edited after the bake: the display refuses the stale transfer, and says so."""
    import bmesh

    bpy = bpy_module
    from prt_addon import api

    bm = bmesh.new()
    bm.from_mesh(scene.sphere.data)
    bm.edges.ensure_lookup_table()
    bmesh.ops.rotate_edges(bm, edges=[bm.edges[20]], use_ccw=True)
    bm.to_mesh(scene.sphere.data)
    bm.free()
    assert api.bake_status(scene.sphere) == "stale"
    refused(bpy, lambda: api.shade(scene.sphere), r"'Sphere': topology changed since the bake: re-bake")
