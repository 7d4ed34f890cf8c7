"""The web viewer (docs/export.md): its JS SH rotation against the core, its build, its image against api.render_view."""

import importlib.util
import json
import os
import shutil
import subprocess

import numpy as np
import pytest

from prt_addon.core.sh import basis as sh, frames, rotation

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SH_ROTATION_JS = os.path.join(ROOT, "web", "src", "sh_rotation.js")

# Tolerances of the viewer's linear image against api.render_view, over the pixels both draw, as
# fractions of the mean radiance there. Measured on the demo scene (order 8, 4 split lights, two
# of them wide: 34 shadow maps, 480x360): mean 0.03-0.04 %, 99th percentile 0.3-0.4 %; what
# differs are pixels on silhouettes and shadow edges, where two rasterisers (llvmpipe,
# SwiftShader) round differently.
MEAN_TOLERANCE = 0.003
P99_TOLERANCE = 0.02
COVERAGE_TOLERANCE = 0.001  # fraction of pixels drawn by one and not the other

NODE_ROTATION = """
import { rotationMatrix, frameRotation, lightInLocalFrame } from %s;
import fs from 'node:fs';
const cases = JSON.parse(fs.readFileSync(0, 'utf8'));
const out = cases.map((c) => ({
  matrix: Array.from(rotationMatrix(c.rotation, c.order)),
  frame: frameRotation(c.linear),
  local: lightInLocalFrame(c.light, c.linear, c.order, c.turn),
}));
console.log(JSON.stringify(out));
"""


def _random_rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def test_js_rotation_matches_the_core(tmp_path):
    """web/src/sh_rotation.js gives the core's rotation matrices (orders 1-8, random rotations),
    frame rotations (scaled, sheared, mirrored) and local-frame lights to 1e-10."""
    if shutil.which("node") is None:
        pytest.skip("node is needed to run the viewer's JavaScript (install Node.js)")
    rng = np.random.default_rng(17)
    cases = []
    for order in range(1, 9):
        for _ in range(3):
            linear = (
                _random_rotation(rng) @ np.diag(rng.uniform(0.3, 2.0, 3)) @ (np.eye(3) + 0.2 * rng.normal(size=(3, 3)))
            )
            if rng.uniform() < 0.5:
                linear = linear @ np.diag([-1.0, 1.0, 1.0])
            light_order = int(rng.integers(1, 10))
            cases.append(
                {
                    "order": order,
                    "rotation": _random_rotation(rng).ravel().tolist(),
                    "linear": linear.ravel().tolist(),
                    "turn": _random_rotation(rng).ravel().tolist(),
                    "light": rng.normal(size=(light_order * light_order, 3)).tolist(),
                }
            )
    script = tmp_path / "rotation.mjs"
    script.write_text(NODE_ROTATION % json.dumps("file://" + SH_ROTATION_JS))
    run = subprocess.run(
        ["node", str(script)], input=json.dumps(cases), capture_output=True, text=True, timeout=120, check=False
    )
    assert run.returncode == 0, run.stderr
    results = json.loads(run.stdout)
    worst = 0.0
    for case, got in zip(cases, results, strict=True):
        n = case["order"]
        r = np.array(case["rotation"]).reshape(3, 3)
        expected = rotation.rotation_matrix(r, n)
        worst = max(worst, np.abs(np.array(got["matrix"]).reshape(n * n, n * n) - expected).max())
        linear = np.array(case["linear"]).reshape(3, 3)
        q, mirrored = frames.frame_rotation(linear)
        assert got["frame"]["mirrored"] == mirrored
        assert np.abs(np.array(got["frame"]["rotation"]).reshape(3, 3) - q).max() < 1e-10
        # docs/export.md, Shading steps 1-2, with the world light first turned by `turn`.
        light = np.array(case["light"])
        padded = np.zeros((n * n, 3))
        m = min(n * n, len(light))
        padded[:m] = light[:m]
        turn = np.array(case["turn"]).reshape(3, 3)
        local = rotation.rotation_matrix(q.T @ turn, n) @ padded
        if mirrored:
            local *= ((-1.0) ** sh.band_of_index(n))[:, None]
        assert np.abs(np.array(got["local"]) - local).max() < 1e-10 * max(1.0, np.abs(local).max())
    assert worst < 1e-10, worst


def test_build_refuses_bad_input(tmp_path):
    """build_web.sh says what is wrong with the .glb or the output path, and leaves no page."""
    for tool in ("node", "npm"):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} is needed to build the web viewer (install Node.js)")
    _tool("setup_node.sh")
    no_prt = tmp_path / "plain.glb"
    header = json.dumps({"asset": {"version": "2.0"}, "scenes": [{"nodes": []}]}).encode()
    header += b" " * (-len(header) % 4)
    no_prt.write_bytes(
        b"glTF"
        + (2).to_bytes(4, "little")
        + (20 + len(header)).to_bytes(4, "little")
        + len(header).to_bytes(4, "little")
        + b"JSON"
        + header
    )
    (tmp_path / "text.glb").write_text("not a glb")
    (tmp_path / "file").write_text("")
    cases = [
        (["--glb", str(tmp_path / "missing.glb")], "no such file"),
        (["--glb", str(tmp_path / "text.glb")], "is not a binary glTF"),
        (["--glb", str(no_prt)], "has no PRT lighting"),
        (["--out", str(tmp_path / "file" / "page.html")], "a part of its folder is a file"),
    ]
    for args, message in cases:
        run = subprocess.run(
            ["bash", os.path.join(ROOT, "scripts", "build_web.sh"), *args]
            + ([] if "--out" in args else ["--out", str(tmp_path / "page.html")]),
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert run.returncode == 2 and message in run.stderr, (args, run.stderr)
        assert "at " not in run.stderr  # a message, not a stack trace
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "plain.glb", "text.glb"]


# --- the viewer in headless Chromium ------------------------------------------------------------


def _tool(script, *args):
    run = subprocess.run(
        ["bash", os.path.join(ROOT, "scripts", script), *args], capture_output=True, text=True, timeout=900
    )
    if run.returncode != 0:
        pytest.fail(f"{script} failed: {run.stderr[-2000:]}")
    return run.stdout.strip().splitlines()[-1]


@pytest.fixture(scope="module")
def browser_tools():
    """Debian's Chromium (installed when missing), the node packages, and the built viewer page."""
    for tool in ("node", "npm"):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} is needed for the web viewer (install Node.js)")
    chromium = _tool("setup_chromium.sh")
    modules = _tool("setup_node.sh")
    page = _tool("build_web.sh")
    return {"chromium": chromium, "modules": modules, "html": page}


def _run_viewer(tools, job, tmp_path):
    path = tmp_path / f"job_{os.path.basename(job['out'])}.json"
    path.write_text(json.dumps(dict(job, chromium=tools["chromium"])))
    run = subprocess.run(
        ["node", os.path.join(ROOT, "web", "tools", "render_headless.mjs"), str(path)],
        capture_output=True,
        text=True,
        timeout=600,
        env=dict(os.environ, PRT_NODE_MODULES=tools["modules"]),
    )
    assert run.returncode == 0, run.stderr[-3000:]
    summary = json.loads(run.stdout.strip().splitlines()[-1])
    assert summary["requests"] == [], summary["requests"]  # offline: nothing but the page itself
    assert not [m for m in summary["console"] if m.startswith(("error", "pageerror"))], summary["console"]
    return summary


def _demo_module():
    spec = importlib.util.spec_from_file_location("prt_demo_script", os.path.join(ROOT, "scripts", "demo.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def demo_scene(bpy_module, addon):
    """The demo's scene (scripts/demo.py) projected and baked at order 8 (the viewer's texture path)."""
    from prt_addon import api
    from prt_addon.blender.display import offscreen

    assert offscreen.ensure_gpu()
    scene = _demo_module().build_scene(_demo_module().bundled_hdri_path("forest"))
    api.project_world(order=8)
    api.bake([scene.objects["Suzanne"], scene.objects["Ground"]], order=8, samples=64)
    return scene


def _turns_and_references(scene, angles, width, height):
    """Per Mapping rotation about Z: the viewer's turn (glTF frame, from the file's lighting at
    angle 0) and api.render_view's image."""
    from prt_addon import api
    from prt_addon.blender.export.gltf import BLENDER_TO_GLTF
    from prt_addon.blender.world import nodes

    turns, images = [], []
    nodes.set_mapping_rotation_euler(scene.world, (0.0, 0.0, 0.0))
    base = nodes.live_sh_rotation(scene.world)
    base = np.eye(3) if base is None else base
    try:
        for angle in angles:
            nodes.set_mapping_rotation_euler(scene.world, (0.0, 0.0, angle))
            turn = nodes.live_sh_rotation(scene.world) @ base.T  # Blender frame
            turns.append((BLENDER_TO_GLTF @ turn @ BLENDER_TO_GLTF.T).ravel().tolist())
            images.append(api.render_view(scene, width, height))
    finally:
        nodes.set_mapping_rotation_euler(scene.world, (0.0, 0.0, 0.0))
    return turns, images


def _compare(reference, file, width, height):
    viewer = np.fromfile(file, np.float32).reshape(height, width, 4)
    drawn_ref, drawn_view = reference[..., 3] > 0, viewer[..., 3] > 0
    both = drawn_ref & drawn_view
    coverage = float((drawn_ref ^ drawn_view).mean())
    diff = np.abs(reference[..., :3] - viewer[..., :3]).max(axis=-1)[both]
    level = float(reference[..., :3][both].mean())
    return {
        "mean": float(diff.mean()) / level,
        "p99": float(np.percentile(diff, 99)) / level,
        "coverage": coverage,
        "level": level,
        "drawn": float(both.mean()),
    }


@pytest.mark.blender
@pytest.mark.gpu
@pytest.mark.browser
@pytest.mark.parametrize("lights", ["split lights", "no lights"])
def test_viewer_matches_render_view(demo_scene, browser_tools, tmp_path, lights, capsys):
    """The viewer's linear image of the exported demo scene from the exported camera is
    api.render_view's at two lighting rotations; with the split lights (shadow maps on both
    sides) from the page loading the file; without them from a page with the .glb embedded, with
    a material's colour and a mirrored node."""
    import bpy

    from prt_addon import api
    from prt_addon.blender.export import glb as glb_module
    from prt_addon.blender.scene import lighting

    scene = demo_scene
    width, height = 480, 360
    suzanne, ground = scene.objects["Suzanne"], scene.objects["Ground"]
    if lights == "no lights":
        lighting.set_lights_override(scene, [])
        # Also a material's base colour (the ground keeps none: Blender's default 0.8) and a
        # mirrored, turned node: both renderers draw the same data, so the bake need not match.
        material = bpy.data.materials.new("PRT test clay")
        material.diffuse_color = (0.9, 0.35, 0.2, 1.0)
        for node in material.node_tree.nodes if material.node_tree else []:
            if node.bl_idname == "ShaderNodeBsdfPrincipled":
                node.inputs["Base Color"].default_value = (0.9, 0.35, 0.2, 1.0)
        suzanne.data.materials.append(material)
        ground.scale, ground.rotation_euler = (-1.0, 1.0, 1.0), (0.0, 0.0, 0.4)
    try:
        count = len(lighting.world_lights(scene))
        assert bool(count) == (lights == "split lights")
        glb = api.export_gltf(str(tmp_path / "demo.glb"))
        turns, references = _turns_and_references(scene, [0.0, 2.1], width, height)
    finally:
        lighting.set_lights_override(scene, None)
        if lights == "no lights":
            suzanne.data.materials.clear()
            bpy.data.materials.remove(material)
            ground.scale, ground.rotation_euler = (1.0, 1.0, 1.0), (0.0, 0.0, 0.0)
    job = {"html": browser_tools["html"], "glb": glb, "width": width, "height": height, "turns": turns}
    if lights == "no lights":  # the page a user double-clicks: the .glb inside it
        page = str(tmp_path / "embedded.html")
        _tool("build_web.sh", "--out", page, "--glb", glb)
        job = dict(job, html=page, glb=None, drag=[150, 0], screenshots=True)
    summary = _run_viewer(browser_tools, dict(job, out=str(tmp_path / "viewer")), tmp_path)
    assert summary["info"]["lights"] == count, summary["info"]  # forest: 3 lights, with samples
    # One map per exported shadow view (forest: two wide lights of 16 views, one compact one).
    exported = glb_module.read(glb)[0]["scenes"][0]["extras"]["PRT_lighting"]["lights"]
    want = [(index, view["wide"]) for index, light in enumerate(exported) for view in light["views"]]
    assert [(v["light"], v["wide"]) for v in summary["info"]["views"]] == want
    assert summary["info"]["camera"] and summary["info"]["orders"] == [8, 8], summary["info"]
    results = [_compare(ref, image["file"], width, height) for ref, image in zip(references, summary["images"])]
    with capsys.disabled():
        print(f"\nviewer vs render_view ({lights}, {summary['renderer'][:60]}):")
        for angle, r in zip([0.0, 2.1], results):
            print(
                f"  rotation {angle:.1f} rad: mean {100 * r['mean']:.3f} %, p99 {100 * r['p99']:.3f} % of the "
                f"mean radiance {r['level']:.3f}; coverage differs on {100 * r['coverage']:.3f} % of pixels"
            )
    for r in results:
        assert r["drawn"] > 0.3  # the scene fills the view: a wrong camera would not
        assert r["mean"] < MEAN_TOLERANCE and r["p99"] < P99_TOLERANCE, results
        assert r["coverage"] < COVERAGE_TOLERANCE, results
    if "drag" in job:  # a mouse drag of 150 pixels to the right turns the lighting 1.5 rad about up
        c, s = np.cos(1.5), np.sin(1.5)
        assert np.allclose(summary["dragTurn"], [c, 0, s, 0, 1, 0, -s, 0, c], atol=1e-9), summary["dragTurn"]
    # The two rotations differ far more than the tolerance: the comparison sees the turn.
    a, b = (np.fromfile(image["file"], np.float32).reshape(height, width, 4) for image in summary["images"])
    assert np.abs(a[..., :3] - b[..., :3]).mean() > 20 * MEAN_TOLERANCE * results[0]["level"]


@pytest.mark.blender
@pytest.mark.gpu
@pytest.mark.browser
def test_viewer_reports_a_file_without_prt(demo_scene, browser_tools, tmp_path):
    """A .glb without the PRT lighting (a plain glTF) is refused with a message, not drawn black."""
    from prt_addon import api
    from prt_addon.blender.export import glb

    path = api.export_gltf(str(tmp_path / "plain.glb"))
    document, chunks = glb.read(path)
    for scene in document["scenes"]:
        scene.get("extras", {}).pop("PRT_lighting", None)
    glb.write(path, document, chunks)
    job = {
        "html": browser_tools["html"],
        "glb": path,
        "width": 64,
        "height": 48,
        "turns": [],
        "out": str(tmp_path / "p"),
    }
    summary = _run_viewer(browser_tools, job, tmp_path)
    assert "has no PRT lighting" in summary.get("error", ""), summary
