"""Texel bakes of a low-poly room against Cycles' image bake of the same UV maps: the error over every object's texels, and no light line where a wall or a box meets the floor."""

import math

import numpy as np
import pytest
from helpers import texel_scenes as ts
from helpers.worlds import bundled_hdri_path

RES = 32
CYCLES_SAMPLES = 128
# Measured (docs/texels.md): 4.6 % at order 8 under sunset.exr, where Cycles' own noise at 128
# samples is 3.0 % (two seeds: the closed room is dark), so about 3.4 % is the bake's own (SH band
# limit, 256 directions); without the ceiling 2.5 % against a noise of 1.8 %.
TOLERANCE = 0.06


@pytest.fixture(scope="module")
def room(bpy_module, addon):
    from prt_addon import api

    bpy = bpy_module
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    world = bpy.data.worlds.new("Sunset")
    scene.world = world
    world.use_nodes = True
    env = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(bundled_hdri_path("sunset"))
    world.node_tree.links.new(env.outputs["Color"], world.node_tree.nodes["Background"].inputs["Color"])
    objs = ts.low_poly_room(bpy)
    api.project_world(scene, order=8, split_lights=True)
    report = api.bake(objs, order=8, samples=256, target="TEXELS", resolution=RES, uv_map=ts.LIGHTMAP)
    ours = {o.name: api.shade(o) for o in objs}
    cycles = ts.cycles_texel_bake(bpy, scene, objs, RES, CYCLES_SAMPLES)
    masks = {o.name: ts.interior_texels(o, RES) for o in objs}
    return {"objs": objs, "report": report, "ours": ours, "cycles": cycles, "masks": masks}


def test_texel_bake_is_within_the_band_limit_and_noise_of_cycles(room, capsys):
    error = ts.relative_rmse(room["ours"], room["cycles"], room["masks"])
    with capsys.disabled():
        print(f"\ntexel bake against Cycles ({CYCLES_SAMPLES} samples): {100 * error:.2f} %")
    assert error < TOLERANCE
    for obj in room["objs"]:  # and no object far off on its own (thin legs straddle shadow edges)
        one = {obj.name: room["masks"][obj.name]}
        assert ts.relative_rmse(room["ours"], room["cycles"], one) < 3 * TOLERANCE, obj.name


def test_the_vertex_bake_of_the_room_cannot_show_it(room, bpy_module):
    """The same room baked per vertex (four values a wall) and read through the UV maps is far
    from Cycles: what the texel bake is for."""
    from prt_addon import api
    from prt_addon.core.transfer import texels

    objs = room["objs"]
    api.bake(objs, order=8, samples=256)
    interpolated = {}
    for obj in objs:
        values = api.shade(obj)
        interpolated[obj.name] = _vertex_values_at_texels(obj, values, texels)
    error = ts.relative_rmse(interpolated, room["cycles"], room["masks"])
    assert error > 5 * ts.relative_rmse(room["ours"], room["cycles"], room["masks"])
    api.bake(objs, order=8, samples=256, target="TEXELS", resolution=RES, uv_map=ts.LIGHTMAP)


def _vertex_values_at_texels(obj, values, texels):
    mesh = obj.data
    from prt_addon.blender.scene import mesh_read

    corners, vertices, world, normals = mesh_read.world_triangles(mesh, np.array(obj.matrix_world))
    uvs = mesh_read.read_corner_uvs(mesh, ts.LIGHTMAP)[corners].astype(np.float64)
    per_corner = values[vertices] if len(values) == len(mesh.vertices) else values[corners]
    samples = texels.texel_samples(uvs, world, normals, RES)
    out = np.zeros((RES * RES, 3))
    out[samples.texels] = np.einsum("pk,pkc->pc", samples.barycentrics[0], per_corner[samples.triangles[0]])
    return out.reshape(RES, RES, 3)


def _texel_positions(obj):
    from prt_addon.blender.scene import mesh_read
    from prt_addon.core.transfer import texels

    corners, _v, world, normals = mesh_read.world_triangles(obj.data, np.array(obj.matrix_world))
    uvs = mesh_read.read_corner_uvs(obj.data, ts.LIGHTMAP)[corners].astype(np.float64)
    samples = texels.texel_samples(uvs, world, normals, RES)
    centre = samples.positions.mean(axis=0)
    return samples.texels, centre


@pytest.mark.parametrize(
    ("name", "near", "far"),
    [
        (
            "Floor",
            lambda p: (p[:, 1] > 1.88) & (np.abs(p[:, 0]) < 1.5),
            lambda p: (p[:, 1] > 1.5) & (p[:, 1] < 1.7) & (np.abs(p[:, 0]) < 1.5),
        ),
        ("Back", lambda p: p[:, 2] < 0.12, lambda p: (p[:, 2] > 0.3) & (p[:, 2] < 0.5)),
        (
            "Floor",
            lambda p: (np.abs(p[:, 0] + 1.0) < 0.2) & (np.abs(p[:, 1] + 0.92) < 0.06),
            lambda p: (np.abs(p[:, 0] + 1.0) < 0.2) & (np.abs(p[:, 1] + 1.3) < 0.08),
        ),
    ],
    ids=["floor at the back wall", "back wall at the floor", "floor at the box"],
)
def test_no_light_line_where_surfaces_meet(room, bpy_module, name, near, far):
    """The texels next to a join against those a little further out: the same ratio as Cycles'
    (a ray leaking under the other surface makes the near row bright; Cycles has none)."""
    obj = next(o for o in room["objs"] if o.name == name)
    flat, positions = _texel_positions(obj)
    ours = (room["ours"][name] @ ts.LUMA).reshape(-1)[flat]
    cycles = (room["cycles"][name] @ ts.LUMA).reshape(-1)[flat]
    a, b = near(positions), far(positions)
    assert a.sum() >= 4
    assert b.sum() >= 4
    ratio_ours, ratio_cycles = ours[a].mean() / ours[b].mean(), cycles[a].mean() / cycles[b].mean()
    assert math.isclose(ratio_ours, ratio_cycles, rel_tol=0.08), (ratio_ours, ratio_cycles)
