"""Back faces against Cycles: a single-sided roof over a floor, each side of it against Cycles' bake of that side.

Cycles bakes the side the normal faces, so the back is Cycles' DIFFUSE / DIRECT bake of the same
roof with its faces reversed (bmesh reverse_faces keeps the vertices in order). The sky is a
smooth known-SH sky with a small bright sun 54 degrees up, split off as a light: the top gets the
sky and the sun, the underside the floor (black in a direct-only bake) and a ring of sky near the
horizon, and no sun. Tolerances are measured: see the figures printed and docs/bake.md, "Back faces".
"""

import numpy as np
from helpers.cycles import cycles_vertex_bake
from helpers.worlds import image_world, sunny_image

CYCLES_SAMPLES = 256
TOLERANCE_TOP = 0.025  # relative RMSE over the roof's vertices (measured 0.8 %)
TOLERANCE_BOTTOM = 0.015  # RMSE relative to the top's mean (measured 0.3 %; the underside is 0.08 of the top)


def _roof_over_floor(bpy, scene):
    image_world(bpy, scene, sunny_image(128, 256, sun=(0.4, 0.8), power=400.0))
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=12, y_subdivisions=12, size=6.0)
    floor = bpy.context.active_object
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=8, y_subdivisions=8, size=2.0, location=(0.0, 0.0, 1.0))
    roof = bpy.context.active_object
    material = bpy.data.materials.new("white")
    for obj in (floor, roof):
        obj.data.materials.append(material)
    return floor, roof


def _reverse_faces(bpy, obj):
    import bmesh

    bm = bmesh.new()
    bm.from_mesh(obj.data)
    bmesh.ops.reverse_faces(bm, faces=bm.faces[:])
    bm.to_mesh(obj.data)
    bm.free()
    obj.data.update()


def test_roof_top_and_underside_against_cycles(bpy_module, empty_scene):
    from prt_addon import api

    bpy, scene = bpy_module, empty_scene
    floor, roof = _roof_over_floor(bpy, scene)
    api.project_world(scene, 8, split_lights=True)
    assert api.world_lights(scene)
    api.bake([floor, roof], order=8, samples=1024)
    assert roof.data["prt_bake"]["back"] == 1 and floor.data["prt_bake"]["back"] == 1
    top, bottom = api.shade(roof, scene), api.shade(roof, scene, side="BACK")
    cycles_top = cycles_vertex_bake(bpy, scene, [roof], CYCLES_SAMPLES)[roof.name]
    _reverse_faces(bpy, roof)
    cycles_bottom = cycles_vertex_bake(bpy, scene, [roof], CYCLES_SAMPLES)[roof.name]
    scale = float(np.mean(cycles_top))
    error_top = float(np.sqrt(np.mean((top - cycles_top) ** 2))) / scale
    error_bottom = float(np.sqrt(np.mean((bottom - cycles_bottom) ** 2))) / scale
    print(
        f"\ntop: PRT {top.mean():.4f} Cycles {cycles_top.mean():.4f}, error {100 * error_top:.2f} %; "
        f"underside: PRT {bottom.mean():.4f} Cycles {cycles_bottom.mean():.4f}, error {100 * error_bottom:.2f} % of the top"
    )
    assert cycles_bottom.mean() < 0.3 * cycles_top.mean()  # the scene does tell the sides apart
    assert error_top < TOLERANCE_TOP
    assert error_bottom < TOLERANCE_BOTTOM
