"""Back faces against Cycles: a single-sided roof over a floor, each side of it against Cycles' bake and render of that side.

Cycles bakes the side the normal faces, so the back is Cycles' DIFFUSE / DIRECT bake of the same
roof with its faces reversed (bmesh reverse_faces keeps the vertices in order). The sky is a
smooth known-SH sky with a small bright sun 54 degrees up, split off as a light: the top gets the
sky and the sun, the underside the floor (black in a direct-only bake) and a ring of sky near the
horizon, and no sun. render_view of each side is also compared with a Cycles render of the same
view (direct light only). Tolerances are measured: see the figures printed and docs/bake.md, "Back faces".
"""

import numpy as np
from helpers.cycles import cycles_vertex_bake
from helpers.roof_scene import reverse_faces, roof_over_floor, sides_against_cycles_render

CYCLES_SAMPLES = 256
TOLERANCE_TOP = 0.025  # relative RMSE over the roof's vertices (measured 0.8 %)
TOLERANCE_BOTTOM = 0.015  # RMSE relative to the top's mean (measured 0.3 %; the underside is 0.08 of the top)


def test_roof_top_and_underside_against_cycles(bpy_module, empty_scene):
    from prt_addon import api

    bpy, scene = bpy_module, empty_scene
    floor, roof = roof_over_floor(bpy, scene)
    api.project_world(scene, 8, split_lights=True)
    assert api.world_lights(scene)
    api.bake([floor, roof], order=8, samples=1024)
    assert roof.data["prt_bake"]["back"] == 1 and floor.data["prt_bake"]["back"] == 1
    top, bottom = api.shade(roof, scene), api.shade(roof, scene, side="BACK")
    cycles_top = cycles_vertex_bake(bpy, scene, [roof], CYCLES_SAMPLES)[roof.name]
    reverse_faces(bpy, roof)
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


def test_render_view_of_each_side_against_a_cycles_render(bpy_module, empty_scene):
    """The roof drawn by render_view from above and from below, against Cycles' render of the
    same view (direct light only, a white diffuse material), over the pixels inside the roof."""
    bpy, scene = bpy_module, empty_scene
    floor, roof = roof_over_floor(bpy, scene)
    errors = sides_against_cycles_render(
        bpy, scene, floor, roof, lambda api, *objs: api.bake(list(objs), order=8, samples=1024), CYCLES_SAMPLES
    )
    print(f"\n(render_view mean, Cycles mean, relative difference of the means, relative RMSE): {errors}")
    assert errors["underside"][1] < 0.3 * errors["top"][1]
    # Measured: means 0.1 % (top) and 0.7 % (underside) apart; the per-pixel RMSE (1.4 %, 5.5 %)
    # is Cycles' noise at 256 samples, the underside being 13 times dimmer.
    assert errors["top"][2] < 0.02 and errors["underside"][2] < 0.03
