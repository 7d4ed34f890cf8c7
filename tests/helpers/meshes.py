"""Meshes built from numpy arrays, and shading under a constant white world."""

import numpy as np


def white_world(bpy, scene, value=1.0):
    world = bpy.data.worlds.new("World")
    if world.node_tree is None:
        world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (value, value, value, 1.0)
    scene.world = world
    return world


def mesh_object(bpy, scene, name, verts, faces, smooth=True):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(map(float, v)) for v in verts], [], [tuple(f) for f in faces])
    if smooth:
        mesh.shade_smooth()
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    return obj


def grid(n, size=1.0, z=0.0):
    x = np.linspace(-size, size, n)
    xx, yy = np.meshgrid(x, x, indexing="ij")
    verts = np.stack([xx.ravel(), yy.ravel(), np.full(n * n, z)], -1)
    faces = [
        (i * n + j, (i + 1) * n + j, (i + 1) * n + j + 1, i * n + j + 1) for i in range(n - 1) for j in range(n - 1)
    ]
    return verts, faces


def shade_white(bpy, scene, objs, order):
    from prt_addon import api

    white_world(bpy, scene)
    api.project_world(scene, order)
    out = [api.shade(o, scene) for o in objs]
    for r in out:
        assert np.all(np.isfinite(r))
        assert r.min() >= 0.0
    return out
