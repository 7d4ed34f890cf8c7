"""Bad input, as a user would give it: what is selected to bake.

Every case ends in a clear message in Blender's report and leaves the .blend exactly as it was;
test_bad_input_bake.py (bake settings, a running bake) and test_bad_input_world.py (the world,
the display) use the same snapshot helpers (tests/helpers/bad_input.py) and baked scene (the
`scene` fixture, tests/helpers/fixtures_bake.py).

Operators run through bpy.ops. In background mode an operator that reports ERROR and returns
CANCELLED makes bpy.ops raise RuntimeError("Error: <message>"), and a failed poll raises
RuntimeError("Operator bpy.ops.<id>.poll() <poll message>"): the tests assert on that text.
The Python API raises ValueError with the same kind of message.

"Exactly as it was" is checked with a snapshot of everything a .blend would save that the
add-on could touch: every mesh's attributes (names, domains, types, values) and ID properties,
every object's transform, selection and visibility, the active object, the scene's ID properties
(scene.prt, prt_world, prt_bake and the stored SH), the world's node tree, and the ID counts.
"""

import numpy as np
import pytest
from helpers.bad_input import bake, refused, select_only

pytestmark = pytest.mark.usefixtures("no_bake_left_running")


# --- snapshot ---------------------------------------------------------------------------------


# --- scene helpers ----------------------------------------------------------------------------


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
