"""Bake scenes: a monkey on a ground plane, an attribute's bytes."""

import json

import numpy as np


def _monkey_on_ground(bpy, ground_cuts=8, smooth=True):
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=ground_cuts, y_subdivisions=ground_cuts, size=6)
    ground = bpy.context.object
    bpy.ops.mesh.primitive_monkey_add(location=(0, 0, 1.0))
    monkey = bpy.context.object
    if smooth:
        monkey.data.shade_smooth()
    return ground, monkey


def _attr_bytes(mesh):
    """{name: (domain, data_type, raw bytes)} of every prt_* attribute, plus the record."""
    out = {}
    for attr in mesh.attributes:
        if attr.name.startswith("prt_"):
            buf = np.empty(len(attr.data) * 4, np.float32)
            mesh.attributes[attr.name].data.foreach_get("color", buf)
            out[attr.name] = (attr.domain, attr.data_type, buf.tobytes())
    record = mesh.get("prt_bake")
    out["record"] = json.dumps(record.to_dict() if record is not None else None, sort_keys=True)
    out["active"] = mesh.color_attributes.active_color_name
    return out
