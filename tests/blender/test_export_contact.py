"""The contact tangent in the .glb (`_PRT_CONTACT`): its accessor, its values in glTF's frame against the closed forms, only with split lights."""

import numpy as np
from helpers.gltf import _read_glb

# glTF -> Blender coordinates: (x, y, z)_glTF -> (x, -z, y) (the transpose of the exporter's map).
TO_BLENDER = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
STEP = np.sqrt(3.0) * 0.5 / 127  # the largest error of a unit vector stored in normalised bytes


def _rows(path, obj):
    """(positions, normals, tangents, the tangents' 4th component, accessor JSON, its view) of
    obj's glTF vertices, the vectors in Blender's local frame."""
    document, accessor = _read_glb(path)
    nodes = {n["name"]: n for n in document["nodes"]}
    mesh = document["meshes"][nodes[obj.name]["mesh"]]
    assert mesh["extras"]["PRT_lighting"]["contact"] == "_PRT_CONTACT"
    parts = [[], [], []]
    for prim in mesh["primitives"]:
        for part, name in zip(parts, ("POSITION", "NORMAL", "_PRT_CONTACT")):
            part.append(accessor(prim["attributes"][name]))
    position, normal, tangent = (np.vstack(p) for p in parts)
    acc = document["accessors"][mesh["primitives"][0]["attributes"]["_PRT_CONTACT"]]
    view = document["bufferViews"][acc["bufferView"]]
    return position @ TO_BLENDER.T, normal @ TO_BLENDER.T, tangent[:, :3] @ TO_BLENDER.T, tangent[:, 3], acc, view


def test_contact_tangent_is_exported_in_the_gltf_frame(baked, tmp_path):
    """Per glTF vertex the stored tangent, turned back to Blender's frame, is the closed form of
    core.transfer.contact's fan (docs/bake.md, "Contacts") within the bytes' step: on the flat
    4 x 4 grid (POINT) the unit diagonal into the grid at its corners, the unit inward
    perpendicular along its edges, 0 inside; on the flat-shaded cube (CORNER) at each corner of
    each face the unit diagonal from the corner to that face's centre. 4 bytes a vertex:
    normalised BYTE VEC4, w = 0."""
    from prt_addon.blender.export import gltf

    _scene, objs = baked
    path = gltf.export_gltf(str(tmp_path / "scene.glb"))

    position, _normal, tangent, w, acc, view = _rows(path, objs["grid"])
    assert (acc["type"], acc["componentType"], acc["normalized"], view.get("byteStride")) == ("VEC4", 5120, True, None)
    assert view["byteLength"] == 4 * acc["count"]
    assert np.all(w == 0.0)
    edge = np.isclose(np.abs(position[:, :2]), 2.0)  # (x, y) on the grid's rim
    expected = np.where(edge, -np.sign(position[:, :2]), 0.0)
    expected = np.c_[expected, np.zeros(len(position))]
    length = np.linalg.norm(expected, axis=1, keepdims=True)
    expected = np.divide(expected, length, out=np.zeros_like(expected), where=length > 0)
    assert edge.any(axis=1).sum() > 8 and edge.all(axis=1).sum() == 4
    np.testing.assert_allclose(tangent, expected, atol=STEP)

    position, normal, tangent, _w, _acc, _view = _rows(path, objs["cube"])
    assert len(position) == 24  # a vertex per face corner
    in_face = position - np.einsum("ij,ij->i", position, normal)[:, None] * normal  # (the face's centre is n * 0.3)
    expected = -in_face / np.linalg.norm(in_face, axis=1, keepdims=True)
    np.testing.assert_allclose(tangent, expected, atol=STEP)


def test_no_contact_tangent_without_split_lights(baked, tmp_path):
    """A file without split lights has no shadow maps to shift: no `_PRT_CONTACT`, no `contact`
    key. With the light the tangents' buffer views hold 4 bytes a glTF vertex."""
    from prt_addon.blender.export import glb, gltf
    from prt_addon.blender.scene import lighting

    scene, _objs = baked
    lit, _chunks = glb.read(gltf.export_gltf(str(tmp_path / "lit.glb"), environment_size=0))
    lights = lighting.world_lights(scene)
    lighting.set_lights_override(scene, [])
    try:
        plain, _chunks = glb.read(gltf.export_gltf(str(tmp_path / "plain.glb"), environment_size=0))
    finally:
        lighting.set_lights_override(scene, lights)
    for mesh in plain["meshes"]:
        assert "contact" not in mesh["extras"]["PRT_lighting"]
        assert not any("_PRT_CONTACT" in p["attributes"] for p in mesh["primitives"])
    prims = [p for m in lit["meshes"] for p in m["primitives"]]
    vertices = sum(lit["accessors"][p["attributes"]["POSITION"]]["count"] for p in prims)
    views = [lit["accessors"][p["attributes"]["_PRT_CONTACT"]]["bufferView"] for p in prims]
    stored = sum(lit["bufferViews"][v]["byteLength"] for v in views)
    print(f"{vertices} glTF vertices: the contact tangents hold {stored} bytes")
    assert stored == 4 * vertices


def test_a_texel_bake_gets_its_corners_tangents(baked, tmp_path):
    """The grid baked per texel instead (its corners' normals: the same flat fan): its glTF
    vertices carry the same closed form as the vertex bake's."""
    from prt_addon import api
    from prt_addon.blender.export import glb, gltf

    _scene, objs = baked
    grid = objs["grid"]
    api.bake([grid], order=2, samples=16, target="TEXELS", uv_map="UVMap", resolution=16)
    path = gltf.export_gltf(str(tmp_path / "texels.glb"), environment_size=0)
    document, _chunks = glb.read(path)
    assert {m["extras"]["PRT_lighting"]["domain"] for m in document["meshes"]} == {"POINT", "CORNER", "TEXEL"}
    position, _normal, tangent, _w, _acc, _view = _rows(path, grid)
    edge = np.isclose(np.abs(position[:, :2]), 2.0)
    expected = np.c_[np.where(edge, -np.sign(position[:, :2]), 0.0), np.zeros(len(position))]
    length = np.linalg.norm(expected, axis=1, keepdims=True)
    expected = np.divide(expected, length, out=np.zeros_like(expected), where=length > 0)
    np.testing.assert_allclose(tangent, expected, atol=STEP)
