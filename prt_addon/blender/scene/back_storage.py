"""The back side's transfer on a mesh: the `prt_tbKK` attributes and the record's `back` flag.

Written after the front transfer by storage.write_bakes (inside its all-or-nothing write), read
by storage.read_bake_record; docs/storage.md, "Back side".
"""

import numpy as np

BACK_PREFIX = "prt_tb"
RECORD = "prt_bake"


def back_attribute_name(k):
    return f"{BACK_PREFIX}{k:02d}"


def is_back_attribute(name):
    return name.startswith(BACK_PREFIX) and name[len(BACK_PREFIX) :].isdigit()


def write_back(mesh, values, domain):
    """Write the (E, n*n) back transfer as prt_tbKK attributes and set the record's `back`, or,
    with values None, remove any left by an earlier bake."""
    names = [a.name for a in mesh.attributes if is_back_attribute(a.name)]
    count = 0 if values is None else (values.shape[1] + 3) // 4
    for name in names:
        attr = mesh.attributes.get(name)
        if int(name[len(BACK_PREFIX) :]) >= count or attr.domain != domain or attr.data_type != "FLOAT_COLOR":
            mesh.attributes.remove(attr)
    if values is None:
        return
    values = np.asarray(values, dtype=np.float32)
    colors = mesh.color_attributes
    active, default = colors.active_color_name, colors.default_color_name
    channel = np.zeros((values.shape[0], 4), dtype=np.float32)
    for k in range(count):
        name = back_attribute_name(k)
        if mesh.attributes.get(name) is None:
            mesh.color_attributes.new(name, "FLOAT_COLOR", domain)
        width = min(4, values.shape[1] - 4 * k)
        channel[:, :width] = values[:, 4 * k : 4 * k + width]
        channel[:, width:] = 0.0
        mesh.attributes[name].data.foreach_set("color", channel.reshape(-1))
    if active and colors.active_color_name != active:
        colors.active_color_name = active
    if default and colors.default_color_name != default:
        colors.default_color_name = default
    mesh[RECORD]["back"] = 1


def missing_back(mesh, record, count, domain):
    """Why the back transfer the record announces is not readable, or "" (also when it has none)."""
    if not int(record.get("back", 0)):
        return ""
    for k in range(count):
        attr = mesh.attributes.get(back_attribute_name(k))
        if attr is None or attr.domain != domain or attr.data_type != "FLOAT_COLOR":
            return f"attribute {back_attribute_name(k)} is missing or changed"
    return ""


def read_back(mesh, count, order, padded=False):
    """(E, n*n) float32 back transfer (4 * count channels when padded)."""
    names = [back_attribute_name(k) for k in range(count)]
    size = len(mesh.attributes[names[0]].data)
    packed = np.empty((count, size * 4), dtype=np.float32)
    for k, name in enumerate(names):
        mesh.attributes[name].data.foreach_get("color", packed[k])
    values = packed.reshape(count, size, 4).transpose(1, 0, 2).reshape(size, count * 4)
    return np.ascontiguousarray(values if padded else values[:, : order * order])
