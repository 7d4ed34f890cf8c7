"""A single-sided roof over a floor under a sunny sky: the scene of the back-face tests, its faces reversed, its pixels, each side's render_view against Cycles' render."""

import warnings

import numpy as np

from helpers.worlds import image_world, sunny_image


def roof_over_floor(bpy, scene, roof_cuts=8):
    """(floor, roof): a 6 x 6 floor grid and a 2 x 2 roof 1 above it (a grid of `roof_cuts`
    subdivisions, 0: a single quad), one white material, under a sky with a sun 54 degrees up."""
    image_world(bpy, scene, sunny_image(128, 256, sun=(0.4, 0.8), power=400.0))
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=12, y_subdivisions=12, size=6.0)
    floor = bpy.context.active_object
    if roof_cuts:
        bpy.ops.mesh.primitive_grid_add(
            x_subdivisions=roof_cuts, y_subdivisions=roof_cuts, size=2.0, location=(0.0, 0.0, 1.0)
        )
    else:
        bpy.ops.mesh.primitive_plane_add(size=2.0, location=(0.0, 0.0, 1.0))
    roof = bpy.context.active_object
    material = bpy.data.materials.new("white")
    for obj in (floor, roof):
        obj.data.materials.append(material)
    return floor, roof


def reverse_faces(bpy, obj):
    """Turn `obj`'s faces over (bmesh reverse_faces keeps the vertices in order)."""
    import bmesh

    bm = bmesh.new()
    bm.from_mesh(obj.data)
    bmesh.ops.reverse_faces(bm, faces=bm.faces[:])
    bm.to_mesh(obj.data)
    bm.free()
    obj.data.update()


def roof_pixels(bpy, scene, cam, roof, size, inset=3):
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


def sides_against_cycles_render(bpy, scene, floor, roof, bake, samples):
    """render_view of the roof from above and from below against Cycles' render of the same view
    (direct light only, a white diffuse material), over the pixels inside the roof, after
    `bake(api, floor, roof)`: {side: (render_view mean, Cycles mean, relative difference of the
    means, relative RMSE)}."""
    from helpers.specular_scenes import cycles_render
    from prt_addon import api
    from prt_addon.blender.display import offscreen

    assert offscreen.ensure_gpu()
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
    bake(api, floor, roof)
    errors = {}
    for side, location, euler in (
        ("top", (0.0, 0.0, 2.6), (0.0, 0.0, 0.0)),
        ("underside", (0.0, 0.0, 0.2), (np.pi, 0.0, 0.0)),
    ):
        cam.location, cam.rotation_euler = location, euler
        bpy.context.view_layer.update()
        mask = roof_pixels(bpy, scene, cam, roof, size)
        prt = offscreen.render_view(scene, size, size)[..., :3].astype(np.float64)[mask]
        cycles = cycles_render(bpy, scene, samples)[mask]
        errors[side] = (float(prt.mean()), float(cycles.mean()), abs(prt.mean() - cycles.mean()) / cycles.mean())
        errors[side] += (float(np.sqrt(np.mean((prt - cycles) ** 2)) / cycles.mean()),)
    return errors
