"""Web tools: the scripts that set up Chromium, node and the viewer, the viewer run headless, its image against api.render_view."""

import dataclasses
import importlib.util
import json
import os
import subprocess

import numpy as np
import pytest

from helpers.paths import ROOT
from helpers.shadow_scenes import cap_light

# Tolerances of the viewer's linear image against api.render_view, over the pixels both draw, as
# fractions of the mean radiance there. Measured on the demo scene (order 8, 4 split lights, two
# of them wide: 34 shadow maps, 480x360): mean 0.03-0.04 %, 99th percentile 0.3-0.4 %; what
# differs are pixels on silhouettes and shadow edges, where two rasterisers (llvmpipe,
# SwiftShader) round differently.
MEAN_TOLERANCE = 0.003
P99_TOLERANCE = 0.02
COVERAGE_TOLERANCE = 0.001  # fraction of pixels drawn by one and not the other


def _tool(script, *args):
    run = subprocess.run(
        ["bash", os.path.join(ROOT, "scripts", script), *args], capture_output=True, text=True, timeout=900
    )
    if run.returncode != 0:
        pytest.fail(f"{script} failed: {run.stderr[-2000:]}")
    return run.stdout.strip().splitlines()[-1]


def run_plugin_page(tools, tmp_path, files, renders, timeout=1200, release=()):
    """web/tools/plugin_headless.mjs on `files` and `renders` (its job's lists; `release`: the files
    freed after the renders, in order): its summary, the page having asked for nothing but itself."""
    job = {
        "chromium": tools["chromium"],
        "out": str(tmp_path / "plugin"),
        "files": files,
        "renders": renders,
        "release": list(release),
    }
    path = tmp_path / "job.json"
    path.write_text(json.dumps(job))
    run = subprocess.run(
        ["node", os.path.join(ROOT, "web", "tools", "plugin_headless.mjs"), str(path)],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=dict(os.environ, PRT_NODE_MODULES=tools["modules"]),
    )
    assert run.returncode == 0, run.stderr[-3000:]
    summary = json.loads(run.stdout.strip().splitlines()[-1])
    assert summary["requests"] == [], summary["requests"]
    return summary


def float_renders(summary, height, width):
    """The summary's renders as (height, width, 4) float32 images."""
    return [np.fromfile(r["file"], np.float32).reshape(height, width, 4) for r in summary["renders"]]


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


def _lights():
    """A wide light (16 samples over a 25 degree cap), a sun and a disc light without samples
    (image frame): one view per sample for the first, one view each for the others."""
    from prt_addon.core.lights.extraction import Light

    wide, _dirs = cap_light((-0.6, -0.5, 1.0), np.radians(25.0))
    sun, _ = cap_light((0.7, 0.2, 0.8), np.radians(1.0))
    sun = dataclasses.replace(sun, power=np.array([1.2, 1.0, 0.8]))
    disc = Light(np.array([0.1, 0.6, 0.9]) / np.linalg.norm([0.1, 0.6, 0.9]), np.array([0.4, 0.5, 0.6]), 0.05)
    return [wide, sun, disc]


def _export(scene, path, lights):
    """Export with `lights` as the scene's split lights (lighting.set_lights_override, which the
    export reads like the projected ones); -> (path, the world lights the export saw)."""
    from prt_addon import api
    from prt_addon.blender.scene import lighting

    lighting.set_lights_override(scene, lights)
    try:
        return api.export_gltf(str(path)), lighting.world_lights(scene)
    finally:
        lighting.set_lights_override(scene, None)


def coloured_material(bpy, name, rgb):
    """A new material of this colour in the viewport and, when it has one, on its Principled BSDF."""
    material = bpy.data.materials.new(name)
    material.diffuse_color = (*rgb, 1.0)
    for node in material.node_tree.nodes if material.node_tree else []:
        if node.bl_idname == "ShaderNodeBsdfPrincipled":
            node.inputs["Base Color"].default_value = (*rgb, 1.0)
    return material
