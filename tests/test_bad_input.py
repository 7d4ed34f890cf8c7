"""Bad input, as a user would give it: the snapshot helpers, the baked scene, and what is selected to bake.

Every case ends in a clear message in Blender's report and leaves the .blend exactly as it was;
test_bad_input_bake.py (bake settings, a running bake) and test_bad_input_world.py (the world,
the display) use the helpers and fixtures defined here.

Operators run through bpy.ops. In background mode an operator that reports ERROR and returns
CANCELLED makes bpy.ops raise RuntimeError("Error: <message>"), and a failed poll raises
RuntimeError("Operator bpy.ops.<id>.poll() <poll message>"): the tests assert on that text.
The Python API raises ValueError with the same kind of message.

"Exactly as it was" is checked with a snapshot of everything a .blend would save that the
add-on could touch: every mesh's attributes (names, domains, types, values) and ID properties,
every object's transform, selection and visibility, the active object, the scene's ID properties
(scene.prt, prt_world, prt_bake and the stored SH), the world's node tree, and the ID counts.
"""

import json
import types

import numpy as np
import pytest
from conftest import bundled_hdri_path

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
