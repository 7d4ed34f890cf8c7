"""The three.js plugin (web/src/plugin.js) in an app page in headless Chromium: images, the app's own objects, tone mapping, the background, bad files."""

import copy
import json
import os
import subprocess

import numpy as np
import pytest
from helpers.paths import ROOT
from helpers.web import MEAN_TOLERANCE, P99_TOLERANCE, _compare, _turns_and_references, run_plugin_page

pytestmark = pytest.mark.gpu  # (it renders the references with the GPU too)

WIDTH, HEIGHT = 320, 240  # the demo camera's 4:3, so the page frames it as Blender does
# Background probes: a narrow camera high above the scene, looking along these glTF directions.
SPIN = 0.7  # radians: the app turns the model about up by this
PROBES = [(1.0, 0.3, 0.0), (0.0, 0.5, 1.0), (-1.0, 0.2, -0.4), (0.3, 0.9, -0.2), (-0.5, 0.1, 1.0), (0.7, 0.4, -1.0)]


def _variant(path, out, change):
    """A copy of the .glb at `path` with change(document) applied to its JSON."""
    from prt_addon.blender.export import glb

    document, chunks = glb.read(path)
    document = copy.deepcopy(document)
    change(document)
    glb.write(out, document, chunks)
    return str(out)


def _suzanne(document):
    return next(
        m for m in document["meshes"] if "PRT_lighting" in m.get("extras", {}) and "Suzanne" in m.get("name", "")
    )


def _strip(document):
    for item in document["scenes"] + document["meshes"]:
        item.get("extras", {}).pop("PRT_lighting", None)


def _bad_files(path, tmp_path):
    def newer(document):
        document["scenes"][0]["extras"]["PRT_lighting"]["version"] = 99

    def newer_mesh(document):
        _suzanne(document)["extras"]["PRT_lighting"]["version"] = 99

    def truncated(document):
        lighting = document["scenes"][0]["extras"]["PRT_lighting"]
        lighting["coefficients"] = lighting["coefficients"][:9]  # a square, but not order 8

    def corrupt(document):
        document["scenes"][0]["extras"]["PRT_lighting"]["lights"][0] = {"direction": "north"}

    def missing(document):
        for prim in _suzanne(document)["primitives"]:
            del prim["attributes"]["_PRT_T5"]

    cases = {"newer": newer, "newer_mesh": newer_mesh, "truncated": truncated, "corrupt": corrupt, "missing": missing}
    return {name: _variant(path, tmp_path / f"{name}.glb", change) for name, change in cases.items()}


def _srgb(x):
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def _world_radiance(scene, directions):
    """The demo world (forest.exr, Mapping rotation 0, strength 1) seen along glTF directions,
    by Blender's equirectangular convention (docs/world.md), averaged over the probe's 6 degree
    square (17 rows, and 17 / cos(latitude) columns)."""
    image = scene.world.node_tree.nodes["Environment Texture"].image
    w, h = image.size
    pixels = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(pixels)
    pixels = pixels.reshape(h, w, 4)[..., :3]
    out = []
    for g in directions:
        g = np.asarray(g, float) / np.linalg.norm(g)
        x, y, z = g[0], -g[2], g[1]  # glTF (x, y, z) = Blender (x, z, -y)
        u = -np.arctan2(y, x) / (2 * np.pi) + 0.5
        v = np.arctan2(z, np.hypot(x, y)) / np.pi + 0.5
        i, j = int(v * h), int(u * w)
        half = int(round(8 / max(np.cos(np.arcsin(g[1])), 0.2)))
        rows = np.clip(np.arange(i - 8, i + 9), 0, h - 1)
        cols = np.arange(j - half, j + half + 1) % w
        out.append(pixels[np.ix_(rows, cols)].reshape(-1, 3).mean(axis=0))
    return np.array(out)


def test_plugin_in_an_app_page(demo_scene, browser_tools, tmp_path, capsys):
    """In one page: the plugin's linear image of the quantised (default) and the float32 file is
    api.render_view's; beside an ordinary lit sphere and the app's lights the PRT pixels do not
    change and the sphere is as without the file; three.js's tone mapping and exposure are applied
    to the PRT output; a file without PRT data draws exactly as without the plugin; the background
    is the world, turned with the lighting; each bad file says what is wrong and still loads."""
    from prt_addon.blender.export import gltf

    scene = demo_scene
    prt = gltf.export_gltf(str(tmp_path / "prt.glb"))
    flt = gltf.export_gltf(str(tmp_path / "float.glb"), transfer="float32")
    _turn, (reference,) = _turns_and_references(scene, [0.0], WIDTH, HEIGHT)
    plain = _variant(prt, tmp_path / "plain.glb", _strip)
    bad = _bad_files(prt, tmp_path)
    files = [{"name": "prt", "glb": prt}, {"name": "float", "glb": flt}, {"name": "plain", "glb": plain}]
    files += [{"name": "packed", "glb": prt, "options": {"transferSource": "packed"}}]
    files += [{"name": "plain_alone", "glb": plain, "plugin": False}]
    files += [{"name": name, "glb": path} for name, path in bad.items()]
    size = {"width": WIDTH, "height": HEIGHT}
    turn = [float(x) for x in np.array([[0.6, 0.0, 0.8], [0.0, 1.0, 0.0], [-0.8, 0.0, 0.6]]).ravel()]
    renders = [
        dict(size, name="prt"),
        dict(size, name="float"),
        dict(size, name="packed"),
        dict(size, name="prt", ordinary=True, appLights=True),
        dict(size, name=None, ordinary=True, appLights=True, camera=None),
        dict(size, name="prt", target="screen", toneMapping="Reinhard", toneExposure=1.5, exposure=1.0),
        dict(size, name="plain", target="screen", appLights=True),
        dict(size, name="plain_alone", target="screen", appLights=True),
    ]
    # The app turns the model by SPIN about up, and the lighting and the camera with it.
    camera = _file_camera(prt)
    c, s_ = np.cos(SPIN), np.sin(SPIN)
    spin = np.array([[c, 0.0, s_], [0.0, 1.0, 0.0], [-s_, 0.0, c]])
    turned_camera = {k: (spin @ np.array(v)).tolist() if k != "fov" else v for k, v in camera.items()}
    renders += [
        dict(size, name="prt", camera=camera),
        dict(size, name="prt", camera=turned_camera, spin=SPIN, turn=spin.ravel().tolist()),
    ]
    probe = {"width": 8, "height": 8, "name": "prt", "background": True}
    for rotation in (None, turn):
        for d in PROBES:
            camera = {"fov": 6.0, "position": [0.0, 60.0, 0.0], "target": [d[0], 60.0 + d[1], d[2]]}
            renders.append(dict(probe, camera=camera, turn=rotation))
    next(r for r in renders if r["name"] is None)["camera"] = _file_camera(
        prt
    )  # the app alone, framed as the file's camera frames it
    summary = run_plugin_page(browser_tools, tmp_path, files, renders, timeout=600)
    images = [
        np.fromfile(r["file"], np.float32 if renders[i].get("target", "float") == "float" else np.uint8)
        for i, r in enumerate(summary["renders"])
    ]
    images = [im.reshape(renders[i]["height"], renders[i]["width"], 4) for i, im in enumerate(images)]
    f = summary["files"]
    _check_files(f)

    # The plugin's image of both files against render_view.
    results = {}
    packed = images.pop(2)  # (the list below as before)
    renders.pop(2)
    for name, image in (("prt", images[0]), ("float", images[1]), ("packed", packed)):
        file = tmp_path / f"{name}.f32"
        image.astype(np.float32).tofile(file)
        results[name] = _compare(reference, file, WIDTH, HEIGHT)
    with capsys.disabled():
        for name, r in results.items():
            print(f"\nplugin vs render_view, {name} file: mean {100 * r['mean']:.3f} %, p99 {100 * r['p99']:.3f} %")
    for r in results.values():
        assert r["drawn"] > 0.3 and r["mean"] < MEAN_TOLERANCE and r["p99"] < P99_TOLERANCE, results
    drawn = images[0][..., 3] > 0
    level = images[0][..., :3][drawn].mean()
    assert np.abs(images[0] - images[1])[..., :3][drawn].mean() < 5e-4 * level  # quantisation adds little

    # Beside the app's objects and lights: PRT pixels unchanged, the sphere (in front of the file's
    # meshes) as without the file.
    app, alone = images[2], images[3]
    sphere = alone[..., 3] > 0
    prt_only = drawn & ~sphere
    assert sphere.sum() > 200 and prt_only.sum() > 0.3 * drawn.sum()
    assert np.abs(app - images[0])[prt_only].max() < 1e-6 * level
    assert np.abs(app - alone)[sphere].max() < 1e-6
    assert alone[sphere][:, 0].mean() > 2 * alone[sphere][:, 2].mean()  # lit by the app's light, red

    # Tone mapping: Reinhard at the renderer's exposure 1.5, after the PRT exposure of 1 stop.
    x = images[0][..., :3] * 1.5 * 2.0
    expected = np.round(255 * _srgb(x / (1 + x)))
    shown = images[4][..., :3].astype(float)
    assert np.abs(shown - expected)[drawn].mean() < 0.6 and np.percentile(np.abs(shown - expected)[drawn], 99) <= 2
    assert np.abs(np.round(255 * _srgb(images[0][..., :3] * 2.0)) - shown)[drawn].mean() > 10  # it is not ignored

    # A glTF without PRT data: the plugin changes nothing.
    assert np.array_equal(images[5], images[6]) and (images[5][..., 3] > 0).mean() > 0.3

    # The model, the lighting and the camera turned together: the same image (each node's light
    # follows its world matrix, the shadow maps are fitted and drawn again).
    still, spun = images[7], images[8]
    file = tmp_path / "spun.f32"
    spun.astype(np.float32).tofile(file)
    moved = _compare(still, file, WIDTH, HEIGHT)
    with capsys.disabled():
        print(
            f"model, lighting and camera turned together: mean {100 * moved['mean']:.3f} %, p99 {100 * moved['p99']:.3f} %"
        )
    assert moved["drawn"] > 0.3 and moved["mean"] < MEAN_TOLERANCE and moved["p99"] < P99_TOLERANCE, moved
    assert moved["coverage"] < 0.002, moved
    assert np.abs(still - images[0])[..., :3].max() < 1e-6 * level  # (the explicit camera is the file's)

    # The background is the world along each direction, turned with the lighting.
    probes = np.array([im[..., :3].reshape(-1, 3).mean(axis=0) for im in images[9:]])
    unturned, turned = probes[: len(PROBES)], probes[len(PROBES) :]
    r = np.array(turn).reshape(3, 3)
    truth = _world_radiance(scene, PROBES)
    truth_turned = _world_radiance(scene, [r.T @ np.array(d) / np.linalg.norm(d) for d in PROBES])
    mirrored = _world_radiance(scene, [(-d[0], d[1], d[2]) for d in PROBES])
    err = lambda got, want: float(np.median(np.abs(got - want).sum(axis=1) / want.sum(axis=1)))
    figures = {
        "unturned": err(unturned, truth),
        "turned": err(turned, truth_turned),
        "mirrored": err(unturned, mirrored),
    }
    with capsys.disabled():
        print(f"background against forest.exr (median relative error): {figures}")
        print("  per probe:", np.abs(unturned - truth).sum(axis=1) / truth.sum(axis=1))
    assert figures["unturned"] < 0.1 and figures["turned"] < 0.1, figures
    assert figures["mirrored"] > 3 * figures["unturned"], figures


def _file_camera(path):
    """The demo file's camera as pluginTest.render takes one (position, a point ahead, fov)."""
    from prt_addon.blender.export import glb

    document, _chunks = glb.read(path)
    node = next(n for n in document["nodes"] if "camera" in n)
    x, y, z, w = node.get("rotation", [0, 0, 0, 1])
    forward = -np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
    position = np.array(node["translation"])
    fov = np.degrees(document["cameras"][node["camera"]]["perspective"]["yfov"])
    return {"fov": float(fov), "position": position.tolist(), "target": (position + forward).tolist()}


def _check_files(f):
    """What the loader made of each file, and what the console said."""
    said = {name: " | ".join(entry["console"]) for name, entry in f.items()}
    errors = {name: [m for m in entry["console"] if m.startswith(("error", "pageerror"))] for name, entry in f.items()}
    # The quantised file's transfer in packed vertex attributes, the float32 one's in a texture.
    assert f["prt"]["info"]["sources"] == ["texture"] * 2 and f["float"]["info"]["sources"] == ["texture"] * 2
    assert f["packed"]["info"]["sources"] == ["packed", "packed"]
    for name in ("prt", "float"):
        assert f[name]["prt"] and not errors[name], said[name]
        assert all(m["prt"] for m in f[name]["meshes"]) and len(f[name]["meshes"]) == 2, f[name]
        assert f[name]["background"]
    assert f["plain"]["prt"] is False and not errors["plain"] and "no PRT lighting" in said["plain"], said["plain"]
    assert [m["material"] for m in f["plain"]["meshes"]] == [m["material"] for m in f["plain_alone"]["meshes"]]
    assert not any(m["prt"] for m in f["plain"]["meshes"])
    expect = {
        "newer": "format version 99, newer than this plugin reads",
        "truncated": "declares order 8 but holds 9 coefficients",
        "corrupt": "light 0 lacks a direction",
        "newer_mesh": "format version 99, newer than this plugin reads",
        "missing": "needs the attributes _PRT_T5",
    }
    for name, message in expect.items():
        assert "error" not in f[name], f[name]  # the scene still loads
        assert len(f[name]["meshes"]) == 2 and any(message in m for m in errors[name]), (name, said[name])
        assert not [m for m in f[name]["console"] if m.startswith("pageerror")], said[name]
    for name in ("newer", "truncated", "corrupt"):  # the lighting is unusable: no PRT at all
        assert f[name]["prt"] is False and not any(m["prt"] for m in f[name]["meshes"]), f[name]
    for name in ("newer_mesh", "missing"):  # one mesh unusable: it keeps its own material
        assert f[name]["prt"] is True
        assert sorted(m["prt"] for m in f[name]["meshes"]) == [False, True], f[name]


def test_readme_example_runs(demo_scene, browser_tools, tmp_path):
    """web/README.md's ten-line example, verbatim (bundled with 'prt-lighting-three' pointing at
    web/src), served over HTTP with a scene.glb beside it, draws the scene with PRT and the world
    behind, with nothing in the console. (The file has no split lights: their shadow maps would
    only make the software renderer slower.)"""
    import bpy

    from prt_addon import api
    from prt_addon.blender.scene import lighting

    lighting.set_lights_override(demo_scene, [])
    try:
        api.export_gltf(str(tmp_path / "scene.glb"))
    finally:
        lighting.set_lights_override(demo_scene, None)
    job = tmp_path / "job.json"
    job.write_text(
        json.dumps({"chromium": browser_tools["chromium"], "dir": str(tmp_path), "width": 320, "height": 240})
    )
    run = subprocess.run(
        ["node", os.path.join(ROOT, "web", "tools", "example_headless.mjs"), str(job)],
        capture_output=True,
        text=True,
        timeout=600,
        env=dict(os.environ, PRT_NODE_MODULES=browser_tools["modules"]),
    )
    assert run.returncode == 0, run.stderr[-3000:]
    summary = json.loads(run.stdout.strip().splitlines()[-1])
    assert not summary["console"], summary["console"]
    assert "/scene.glb" in summary["served"] and all(r.startswith("http://127.0.0.1:") for r in summary["requests"])
    assert summary["draws"][1] > summary["draws"][0] > 0  # the animation loop runs
    image = bpy.data.images.load(str(tmp_path / "example.png"))
    try:
        w, h = image.size
        pixels = np.empty(w * h * image.channels, np.float32)
        image.pixels.foreach_get(pixels)
    finally:
        bpy.data.images.remove(image)
    rgb = pixels.reshape(h, w, -1)[::-1, :, :3]  # (row 0 the top)
    sky, ground = rgb[: h // 8], rgb[-h // 8 :]
    assert sky.std() > 0.02 and sky.mean() < 0.9  # the forest behind, not a flat clear colour
    assert ground.mean() > 0.6 > sky.mean()  # the lit white ground in front of it
