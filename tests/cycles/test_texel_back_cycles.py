"""The back side of a texel bake against Cycles: a single-quad roof over a floor, each side against Cycles' image bake and render of that side.

The scene of test_back_faces_cycles.py with the roof a single quad baked per texel (its UVMap,
the unit square): Cycles' DIFFUSE / DIRECT image bake of the roof is the top, and of the roof
with its faces reversed (bmesh reverse_faces: the loops and their UVs reversed together, so the
texels stay where they were) the underside. The sky is smooth with a small bright sun 54 degrees
up, split off as a light. render_view of each side is compared with Cycles' render of the same
view (direct light only). Tolerances are measured: see the figures printed and docs/bake.md,
"Back faces".
"""

import warnings

import numpy as np
from helpers.texel_scenes import cycles_texel_bake, interior_texels
from helpers.worlds import image_world, sunny_image

CYCLES_SAMPLES = 256
RESOLUTION = 16
TOLERANCE_TOP = 0.03  # relative RMSE over the roof's 240 interior texels (measured 1.5 %)
TOLERANCE_BOTTOM = 0.01  # RMSE relative to the top's mean (measured 0.4 %; the underside is 0.08 of the top)


def _roof_over_floor(bpy, scene):
    image_world(bpy, scene, sunny_image(128, 256, sun=(0.4, 0.8), power=400.0))
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=12, y_subdivisions=12, size=6.0)
    floor = bpy.context.active_object
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(0.0, 0.0, 1.0))
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


def _bake(api, floor, roof):
    api.bake([floor, roof], order=8, samples=1024, target="TEXELS", uv_map="UVMap", resolution=RESOLUTION)


def test_texel_roof_top_and_underside_against_cycles(bpy_module, empty_scene):
    from prt_addon import api

    bpy, scene = bpy_module, empty_scene
    floor, roof = _roof_over_floor(bpy, scene)
    api.project_world(scene, 8, split_lights=True)
    assert api.world_lights(scene)
    _bake(api, floor, roof)
    assert roof.data["prt_bake"]["domain"] == "TEXEL" and roof.data["prt_bake"]["back"] == 1
    top, bottom = api.shade(roof, scene), api.shade(roof, scene, side="BACK")
    mask = interior_texels(roof, RESOLUTION, "UVMap")
    cycles_top = cycles_texel_bake(bpy, scene, [roof], RESOLUTION, CYCLES_SAMPLES, uv_name="UVMap")[roof.name]
    _reverse_faces(bpy, roof)
    cycles_bottom = cycles_texel_bake(bpy, scene, [roof], RESOLUTION, CYCLES_SAMPLES, uv_name="UVMap")[roof.name]
    top, bottom, cycles_top, cycles_bottom = (x[mask] for x in (top, bottom, cycles_top, cycles_bottom))
    scale = float(np.mean(cycles_top))
    error_top = float(np.sqrt(np.mean((top - cycles_top) ** 2))) / scale
    error_bottom = float(np.sqrt(np.mean((bottom - cycles_bottom) ** 2))) / scale
    print(
        f"\n{mask.sum()} texels; top: PRT {top.mean():.4f} Cycles {cycles_top.mean():.4f}, error {100 * error_top:.2f} %; "
        f"underside: PRT {bottom.mean():.4f} Cycles {cycles_bottom.mean():.4f}, error {100 * error_bottom:.2f} % of the top"
    )
    assert mask.sum() >= 100
    assert cycles_bottom.mean() < 0.3 * cycles_top.mean()  # the scene does tell the sides apart
    assert error_top < TOLERANCE_TOP
    assert error_bottom < TOLERANCE_BOTTOM


def _roof_pixels(bpy, scene, cam, roof, size, inset=3):
    """(H, W) bool: the pixels well inside the roof's square in the camera's picture."""
    corners = np.array([roof.matrix_world @ v.co for v in roof.data.vertices])
    depsgraph = bpy.context.evaluated_depsgraph_get()
    proj = np.array(cam.calc_matrix_camera(depsgraph, x=size, y=size)) @ np.array(cam.matrix_world.inverted())
    clip = np.c_[corners, np.ones(len(corners))] @ proj.T
    ndc = clip[:, :2] / clip[:, 3:4]
    cols, rows = (ndc[:, 0] + 1) * 0.5 * size, (1 - ndc[:, 1]) * 0.5 * size
    mask = np.zeros((size, size), bool)
    c0, c1 = max(0, int(cols.min()) + inset), min(size, int(cols.max()) - inset)
    r0, r1 = max(0, int(rows.min()) + inset), min(size, int(rows.max()) - inset)
    mask[r0:r1, c0:c1] = True
    return mask


def test_texel_render_view_of_each_side_against_a_cycles_render(bpy_module, empty_scene):
    """The texel-baked roof drawn by render_view from above and from below, against Cycles'
    render of the same view (direct light only, white diffuse), over the pixels inside the roof."""
    from helpers.specular_scenes import cycles_render

    from prt_addon import api
    from prt_addon.blender.display import offscreen

    assert offscreen.ensure_gpu()
    bpy, scene = bpy_module, empty_scene
    floor, roof = _roof_over_floor(bpy, scene)
    material = roof.data.materials[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        material.use_nodes = True
    tree = material.node_tree
    tree.nodes.clear()
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    tree.links.new(diffuse.outputs["BSDF"], output.inputs["Surface"])
    scene.prt_display.albedo_source = "WHITE"
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    cam.data.lens = 12.0
    scene.camera = cam
    size = 96
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    api.project_world(scene, 8, split_lights=True)
    _bake(api, floor, roof)
    errors = {}
    for side, location, euler in (
        ("top", (0.0, 0.0, 2.6), (0.0, 0.0, 0.0)),
        ("underside", (0.0, 0.0, 0.2), (np.pi, 0.0, 0.0)),
    ):
        cam.location, cam.rotation_euler = location, euler
        bpy.context.view_layer.update()
        mask = _roof_pixels(bpy, scene, cam, roof, size)
        prt = offscreen.render_view(scene, size, size)[..., :3].astype(np.float64)[mask]
        cycles = cycles_render(bpy, scene, CYCLES_SAMPLES)[mask]
        errors[side] = (float(prt.mean()), float(cycles.mean()), abs(prt.mean() - cycles.mean()) / cycles.mean())
        errors[side] += (float(np.sqrt(np.mean((prt - cycles) ** 2)) / cycles.mean()),)
    print(f"\n(render_view mean, Cycles mean, relative difference of the means, relative RMSE): {errors}")
    assert errors["underside"][1] < 0.3 * errors["top"][1]
    # Measured: means 0.1 % (top) and 1.4 % (underside) apart; the per-pixel RMSE (1.4 %, 5.5 %)
    # is Cycles' noise at 256 samples, the underside being 13 times dimmer.
    assert errors["top"][2] < 0.02 and errors["underside"][2] < 0.03
