"""Bad input to the world projection and the display: each a clear message, the .blend unchanged.

The snapshot helpers and the baked scene are in test_bad_input.py.
"""

import pytest
from helpers.bad_input import refused

pytestmark = pytest.mark.usefixtures("no_bake_left_running")


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
