"""The bad-input tests' tools: refusals, snapshots of what a refused action must leave unchanged."""

import json

import numpy as np
import pytest


def _idprops(owner):
    out = {}
    for key in owner.keys():
        value = owner[key]
        if hasattr(value, "to_dict"):
            value = value.to_dict()
        elif hasattr(value, "to_list"):
            value = value.to_list()
        out[key] = value
    return json.dumps(out, sort_keys=True, default=repr)


def _attribute_values(attr):
    key = {
        "FLOAT_COLOR": "color",
        "BYTE_COLOR": "color",
        "FLOAT_VECTOR": "vector",
        "FLOAT": "value",
        "INT": "value",
        "BOOLEAN": "value",
    }.get(attr.data_type)
    if key is None or len(attr.data) == 0:
        return None
    width = {"color": 4, "vector": 3, "value": 1}[key]
    dtype = {"INT": np.int32, "BOOLEAN": bool}.get(attr.data_type, np.float32)
    buf = np.empty(len(attr.data) * width, dtype)
    attr.data.foreach_get(key, buf)
    return buf.tobytes()


def _socket_value(socket):
    value = getattr(socket, "default_value", None)
    try:
        return tuple(value)
    except TypeError:
        return value


def snapshot(bpy):
    """Everything the add-on could change in a .blend, as comparable plain data."""
    snap = {}
    for mesh in bpy.data.meshes:
        attrs = []
        for attr in mesh.attributes:
            attrs.append((attr.name, attr.domain, attr.data_type, _attribute_values(mesh.attributes[attr.name])))
        snap[f"mesh:{mesh.name}:{mesh.library}"] = (
            sorted(attrs, key=lambda a: a[0]),
            _idprops(mesh),
            mesh.color_attributes.active_color_name,
        )
    for obj in bpy.data.objects:
        snap[f"object:{obj.name}:{obj.library}"] = (
            tuple(tuple(row) for row in obj.matrix_world),
            obj.select_get(),
            obj.hide_get(),
            obj.hide_viewport,
            obj.data.name if obj.data else None,
            obj.mode,
            _idprops(obj),
        )
    view_layer = bpy.context.view_layer
    snap["active"] = view_layer.objects.active.name if view_layer.objects.active else None
    for scene in bpy.data.scenes:
        snap[f"scene:{scene.name}"] = (_idprops(scene), scene.world.name if scene.world else None)
    for world in bpy.data.worlds:
        tree = world.node_tree
        nodes = []
        if tree is not None:
            for node in tree.nodes:
                nodes.append(
                    (
                        node.name,
                        node.bl_idname,
                        node.mute,
                        getattr(getattr(node, "image", None), "name", None),
                        tuple((s.identifier, _socket_value(s)) for s in node.inputs),
                    )
                )
            links = sorted(
                (l.from_node.name, l.from_socket.identifier, l.to_node.name, l.to_socket.identifier) for l in tree.links
            )
        else:
            links = []
        snap[f"world:{world.name}"] = (sorted(nodes, key=repr), links, tuple(world.color), _idprops(world))
    for image in bpy.data.images:
        snap[f"image:{image.name}"] = (image.filepath, image.source, tuple(image.size))
    snap["counts"] = {
        name: len(getattr(bpy.data, name))
        for name in (
            "objects",
            "meshes",
            "images",
            "worlds",
            "materials",
            "node_groups",
            "scenes",
            "libraries",
            "curves",
            "collections",
        )
    }
    return snap


def assert_unchanged(before, after):
    # repr: NaN compares unequal to itself but prints the same.
    changed = sorted(k for k in set(before) | set(after) if repr(before.get(k)) != repr(after.get(k)))
    assert not changed, f"the .blend changed: {changed}"


def refused(bpy, call, match):
    """Run call(), which must fail with a message matching `match`; the .blend must not change.
    Returns the message."""
    before = snapshot(bpy)
    with pytest.raises((RuntimeError, ValueError)) as info:
        call()
    message = str(info.value)
    assert __import__("re").search(match, message), message
    assert_unchanged(before, snapshot(bpy))
    return message


def select_only(bpy, *objects):
    bpy.ops.object.select_all(action="DESELECT")
    for obj in objects:
        obj.select_set(True)
    bpy.context.view_layer.objects.active = objects[0] if objects else None


def bake(bpy):
    return bpy.ops.prt.bake_transfer()
