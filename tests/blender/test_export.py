"""The glTF export: transfer round trip, extras, the user's data untouched, bad input, validator."""

import json
import os
import stat
import subprocess
import sys

import numpy as np
import pytest
from helpers.gltf import VALIDATE_JS, _assert_rows_match, _from_gltf, _read_glb, _stored_rows, _transfer


def _user_state(bpy):
    state = {
        "selected": sorted(o.name for o in bpy.context.view_layer.objects if o.select_get()),
        "active": getattr(bpy.context.view_layer.objects.active, "name", None),
        "meshes": {},
    }
    for mesh in bpy.data.meshes:
        attrs = {}
        for a in mesh.attributes:
            if a.data_type == "FLOAT_COLOR":
                buf = np.empty(len(a.data) * 4, np.float32)
                a.data.foreach_get("color", buf)
                attrs[a.name] = (a.domain, buf.tobytes())
            else:
                attrs[a.name] = (a.domain, a.data_type)
        colors = mesh.color_attributes
        state["meshes"][mesh.name] = (attrs, colors.active_color_name, colors.default_color_name, sorted(mesh.keys()))
    state["objects"] = sorted(o.name for o in bpy.data.objects)
    state["scene_keys"] = sorted(bpy.context.scene.keys())
    return state


@pytest.mark.parametrize("transfer", ["float32", "snorm16"])
def test_export_round_trip(baked, bpy_module, tmp_path, transfer):
    """The file holds each stored transfer row and position (float32 to 2e-5, the default snorm16
    to its quantisation step), the lighting and its lights, and the user's data are untouched."""
    from prt_addon.blender.export import gltf
    from prt_addon.blender.world import projection

    bpy = bpy_module
    scene, objs = baked
    before = _user_state(bpy)
    path = gltf.export_gltf(str(tmp_path / "scene.glb"), transfer=transfer)
    assert os.path.isfile(path) and os.listdir(tmp_path) == ["scene.glb"]
    assert _user_state(bpy) == before
    document, accessor = _read_glb(path)
    world = document["scenes"][0]["extras"]["PRT_lighting"]
    expected = gltf.to_gltf_frame(projection.current_world_coeffs(scene))
    assert world["order"] == 4
    assert np.allclose(world["coefficients"], expected, atol=1e-12)
    assert len(world["lights"]) == 1
    assert np.allclose(world["lights"][0]["direction"], [0.0, 0.8, -0.6])
    assert np.allclose(world["lights"][0]["power"], [3.0, 2.0, 1.0])
    assert world["lights"][0]["angle"] == 0.05
    # A light without samples (its disc): null samples, the shadow filter's disc is its angle.
    assert world["lights"][0]["samples"] is None
    assert world["lights"][0]["weights"] is None
    assert world["lights"][0]["shadow_angle"] == 0.05
    # Its one shadow view (docs/export.md, "Shadow views"): a compact map along it, no sample indices.
    (view,) = world["lights"][0]["views"]
    assert np.allclose(view["direction"], [0.0, 0.8, -0.6])
    assert view["angle"] == 0.05
    assert view["samples"] is None
    assert view["wide"] is False
    nodes = {n["name"]: n for n in document["nodes"]}
    for name, order, domain in (("sphere", 3, "POINT"), ("grid", 3, "POINT"), ("cube", 4, "CORNER")):
        obj = objs[name]
        mesh = document["meshes"][nodes[obj.name]["mesh"]]
        meta = mesh["extras"]["PRT_lighting"]
        assert (meta["order"], meta["domain"], meta["frame"]) == (order, domain, "GLTF_NODE_LOCAL")
        pos_all, t_all = [], []
        for prim in mesh["primitives"]:
            names = [k for k in prim["attributes"] if k.startswith("_PRT_T")]
            assert names == meta["attributes"] == [f"_PRT_T{k}" for k in range((order * order + 3) // 4)]
            assert all(document["accessors"][prim["attributes"][k]]["type"] == "VEC4" for k in names)
            assert not any(k.startswith("COLOR_") for k in prim["attributes"])
            t_all.append(_transfer(document, accessor, mesh, prim))
            p = accessor(prim["attributes"]["POSITION"]).astype(np.float64)
            pos_all.append(np.stack([p[:, 0], -p[:, 2], p[:, 1]], axis=1))
        stored_pos, stored_t = _stored_rows(obj)
        assert meta["transfer_encoding"] == transfer and meta["version"] == (1 if transfer == "float32" else 2)
        # snorm16: at most half a step (scale / 32767) per stored component, and the rotation back
        # to Blender's frame mixes at most 2l + 1 <= 7 of them (orthogonal per band).
        step = max(max(d["scale"]) for d in meta["decode"]) / 32767 if transfer != "float32" else 0.0
        tol = 2e-5 + 0.5 * step * np.sqrt(7)
        _assert_rows_match(stored_pos, stored_t, np.vstack(pos_all), _from_gltf(np.vstack(t_all)), tol=tol)


def test_reimport_has_the_transfer(baked, bpy_module, tmp_path):
    """A float32 file imported by Blender's glTF importer has the transfer as attributes (a
    quantised one would arrive as q / K: Blender's importer does not know the decode table)."""
    from prt_addon.blender.export import gltf

    bpy = bpy_module
    _scene, objs = baked
    stored = {name: _stored_rows(obj) for name, obj in objs.items()}
    names = {name: obj.name for name, obj in objs.items()}
    path = gltf.export_gltf(str(tmp_path / "scene.glb"), transfer="float32")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=path)
    for key, (stored_pos, stored_t) in stored.items():
        obj = bpy.data.objects[names[key]]
        mesh = obj.data
        count = (stored_t.shape[1] + 3) // 4
        columns = []
        for k in range(count):
            attr = mesh.attributes[f"_PRT_T{k}"]
            assert attr.domain == "POINT", attr.domain
            buf = np.empty(len(attr.data) * 4, np.float32)
            prop = "color" if attr.data_type in ("FLOAT_COLOR", "BYTE_COLOR") else "vector"
            attr.data.foreach_get(prop, buf)
            columns.append(buf.reshape(-1, 4))
        values = np.hstack(columns)[:, : stored_t.shape[1]].astype(np.float64)
        co = np.empty(len(mesh.vertices) * 3, np.float32)
        mesh.vertices.foreach_get("co", co)
        _assert_rows_match(stored_pos, stored_t, co.reshape(-1, 3).astype(np.float64), _from_gltf(values))


def test_bad_input_leaves_nothing(baked, bpy_module, tmp_path):
    from prt_addon import api

    bpy = bpy_module
    scene, objs = baked
    before = _user_state(bpy)
    plain = bpy.data.objects.new("plain", bpy.data.meshes.new("plain"))
    scene.collection.objects.link(plain)
    before = _user_state(bpy)
    with pytest.raises(ValueError, match="none of the objects holds a PRT bake"):
        api.export_gltf(str(tmp_path / "a.glb"), [plain])
    with pytest.raises(ValueError, match="does not exist"):
        api.export_gltf(str(tmp_path / "missing" / "a.glb"))
    with pytest.raises(ValueError, match=r"\.glb"):
        api.export_gltf(str(tmp_path / "a.gltf"))
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(stat.S_IRUSR | stat.S_IXUSR)
    if not os.access(locked, os.W_OK):  # (root can write anywhere)
        with pytest.raises(ValueError, match="permission denied"):
            api.export_gltf(str(locked / "a.glb"))
    locked.chmod(stat.S_IRWXU)
    # An attribute of the user's in the way: refused after the first attributes were added.
    cube = objs["cube"].data
    cube.attributes.new("_PRT_T2", "FLOAT", "POINT")
    before = _user_state(bpy)
    with pytest.raises(ValueError, match="already has an attribute '_PRT_T2'"):
        api.export_gltf(str(tmp_path / "b.glb"))
    assert _user_state(bpy) == before
    cube.attributes.remove(cube.attributes["_PRT_T2"])
    # The exporter itself failing.
    before = _user_state(bpy)
    from prt_addon.blender.export import gltf

    def failing(path, _meshes):
        open(path, "wb").close()  # a partial file, which must not stay
        raise gltf.ExportError("the glTF exporter failed: simulated failure")

    real = gltf._run_exporter
    gltf._run_exporter = failing
    try:
        with pytest.raises(ValueError, match="simulated failure"):
            api.export_gltf(str(tmp_path / "c.glb"))
    finally:
        gltf._run_exporter = real
    assert _user_state(bpy) == before
    # A stale bake.
    sphere = objs["sphere"].data
    sphere.vertices.add(1)
    with pytest.raises(ValueError, match="stale"):
        api.export_gltf(str(tmp_path / "d.glb"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["locked"]
    assert not list(locked.iterdir())


def test_exporter_add_on_enabled_when_needed(baked, bpy_module, tmp_path):
    import addon_utils

    from prt_addon import api

    addon_utils.disable("io_scene_gltf2")
    try:
        assert "gltf" not in dir(bpy_module.ops.export_scene)
        api.export_gltf(str(tmp_path / "e.glb"))
        assert (tmp_path / "e.glb").is_file()
    finally:
        addon_utils.enable("io_scene_gltf2", default_set=True)


def test_operator_and_menu(baked, bpy_module, tmp_path):
    bpy = bpy_module
    from prt_addon.blender.ops import export as export_ops

    assert export_ops.menu_func in bpy.types.TOPBAR_MT_file_export._dyn_ui_initialize()
    assert bpy.ops.prt.export_gltf(filepath=str(tmp_path / "op.glb")) == {"FINISHED"}
    assert (tmp_path / "op.glb").is_file()
    with pytest.raises(RuntimeError, match="does not exist"):
        bpy.ops.prt.export_gltf(filepath=str(tmp_path / "no" / "op.glb"))
    # The dialog's Transfer setting is the API's transfer encoding.
    encodings = {}
    for choice in ("float32", "snorm8"):
        path = str(tmp_path / f"op_{choice}.glb")
        assert bpy.ops.prt.export_gltf(filepath=path, transfer=choice) == {"FINISHED"}
        document, _binary = _read_glb(path)
        metas = [m["extras"]["PRT_lighting"] for m in document["meshes"] if "PRT_lighting" in m.get("extras", {})]
        encodings[choice] = {m["transfer_encoding"] for m in metas}
    assert encodings == {"float32": {"float32"}, "snorm8": {"snorm8"}}


def test_khronos_validator(baked, tmp_path, validator_modules):
    from prt_addon import api

    path = api.export_gltf(str(tmp_path / "v.glb"))
    env = dict(os.environ, NODE_PATH=validator_modules)
    out = subprocess.run(["node", "-e", VALIDATE_JS, path], capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    issues = json.loads(out.stdout)
    assert issues["numErrors"] == 0, [m for m in issues["messages"] if m["severity"] == 0]
    print(issues["numWarnings"], "warnings", file=sys.stderr)


def test_shared_mesh_and_parent(baked, bpy_module, tmp_path):
    """A linked duplicate (one mesh, two objects) and a parented object export once per mesh."""
    from prt_addon import api

    bpy = bpy_module
    scene, objs = baked
    twin = bpy.data.objects.new("twin", objs["cube"].data)
    scene.collection.objects.link(twin)
    twin.parent = objs["sphere"]
    twin.location = (2.0, 0.0, 0.0)
    before = _user_state(bpy)
    path = api.export_gltf(str(tmp_path / "shared.glb"))
    assert _user_state(bpy) == before
    document, _accessor = _read_glb(path)
    nodes = {n["name"]: n for n in document["nodes"]}
    assert nodes["twin"]["mesh"] == nodes[objs["cube"].name]["mesh"]
    assert document["meshes"][nodes["twin"]["mesh"]]["extras"]["PRT_lighting"]["order"] == 4


def test_scene_camera_and_view_exported(baked, bpy_module, tmp_path):
    """Exporting the scene's baked objects also writes its camera (a viewer opens at that view)
    and the view exposure; an explicit object list writes only what it lists."""
    from prt_addon import api

    bpy = bpy_module
    scene, objs = baked
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera)
    camera.location = (4.0, -5.0, 3.0)
    camera.rotation_euler = (1.1, 0.0, 0.7)
    scene.camera = camera
    scene.render.resolution_x, scene.render.resolution_y = 480, 360
    scene.view_settings.exposure = -1.5
    document, _accessor = _read_glb(api.export_gltf(str(tmp_path / "cam.glb")))
    assert len(document["cameras"]) == 1
    perspective = document["cameras"][0]["perspective"]
    assert abs(perspective["aspectRatio"] - 480 / 360) < 1e-6
    # Sensor fit AUTO, landscape: the 36 mm sensor spans the width.
    assert abs(perspective["yfov"] - 2 * np.arctan(18.0 / camera.data.lens * 360 / 480)) < 1e-5
    view = document["scenes"][0]["extras"]["PRT_lighting"]["view"]
    assert view == {"exposure": -1.5, "view_transform": scene.view_settings.view_transform}
    document, _accessor = _read_glb(api.export_gltf(str(tmp_path / "only.glb"), [objs["sphere"]]))
    assert "cameras" not in document
