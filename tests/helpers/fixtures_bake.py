"""Bake fixtures: the bake operators and mesh reading modules, a baked scene for the bad-input tests, no modal bake left running."""

import types

import pytest

from helpers.worlds import bundled_hdri_path


@pytest.fixture
def no_bake_left_running(addon):
    """No modal bake left running after the test (used by the bad-input modules)."""
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


@pytest.fixture
def bake_ops(addon):
    from prt_addon.blender.ops import bake as bake_ops

    return bake_ops


@pytest.fixture
def mesh_io(addon):
    from prt_addon.blender.scene import mesh_read

    return mesh_read
