"""Cycles as ground truth: a per-vertex DIFFUSE bake of some objects."""

import numpy as np


def cycles_vertex_bake(bpy, scene, objects, samples, passes=("DIRECT",), bounces=None, domain="POINT"):
    """{object name: (V, 3)} E/pi per vertex (white albedo; per corner with domain "CORNER") from
    Cycles' DIFFUSE bake of the objects alone, with `passes` and, when given, `bounces` diffuse
    bounces; the temporary colour attribute is removed again."""
    bpy.ops.object.select_all(action="DESELECT")
    for obj in objects:
        colours = obj.data.color_attributes
        colours.active_color = colours.new("cycles", "FLOAT_COLOR", domain)
        obj.select_set(True)
    bpy.context.view_layer.objects.active = objects[0]
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    if bounces is not None:
        scene.cycles.diffuse_bounces = bounces
        scene.cycles.max_bounces = bounces + 4
        scene.cycles.glossy_bounces = scene.cycles.transmission_bounces = 0
    bpy.ops.object.bake(type="DIFFUSE", pass_filter=set(passes), target="VERTEX_COLORS", use_clear=True)
    out = {}
    for obj in objects:
        colours = obj.data.color_attributes
        values = np.empty(len(colours["cycles"].data) * 4, np.float32)
        colours["cycles"].data.foreach_get("color", values)
        out[obj.name] = values.reshape(-1, 4)[:, :3].astype(np.float64)
        colours.remove(colours["cycles"])
    return out
