"""The three.js plugin on a texel bake (the ground per texel, Suzanne per vertex) in headless Chromium, against api.render_view."""

import json
import os
import subprocess

import numpy as np
import pytest
from helpers.paths import ROOT
from helpers.web import MEAN_TOLERANCE, P99_TOLERANCE, _compare, _turns_and_references

pytestmark = pytest.mark.gpu  # (render_view draws the references with the GPU)

WIDTH, HEIGHT = 320, 240


def _plugin_images(browser_tools, tmp_path, files, renders):
    job = {"chromium": browser_tools["chromium"], "out": str(tmp_path / "plugin"), "files": files, "renders": renders}
    path = tmp_path / "job.json"
    path.write_text(json.dumps(job))
    run = subprocess.run(
        ["node", os.path.join(ROOT, "web", "tools", "plugin_headless.mjs"), str(path)],
        capture_output=True,
        text=True,
        timeout=600,
        env=dict(os.environ, PRT_NODE_MODULES=browser_tools["modules"]),
    )
    assert run.returncode == 0, run.stderr[-3000:]
    summary = json.loads(run.stdout.strip().splitlines()[-1])
    assert summary["requests"] == [], summary["requests"]
    images = [np.fromfile(r["file"], np.float32).reshape(HEIGHT, WIDTH, 4) for r in summary["renders"]]
    return summary["files"], images


def test_the_plugin_draws_a_texel_bake_as_render_view(texel_demo_scene, browser_tools, tmp_path, capsys):
    """The ground's texels relit in the page and looked up per pixel: the image is render_view's at
    two lighting rotations, for the 16-bit (default) and the 8-bit file; the ground's texels decide
    its pixels (drawing it with a constant radiance instead is far off)."""
    from prt_addon import api

    scene = texel_demo_scene
    angles = [0.0, 2.1]
    turns, references = _turns_and_references(scene, angles, WIDTH, HEIGHT)
    files = [
        {"name": "texel16", "glb": api.export_gltf(str(tmp_path / "t16.glb"))},
        {"name": "texel8", "glb": api.export_gltf(str(tmp_path / "t8.glb"), transfer="snorm8")},
    ]
    size = {"width": WIDTH, "height": HEIGHT}
    renders = [dict(size, name=f["name"], turn=t) for f in files for t in turns]
    info, images = _plugin_images(browser_tools, tmp_path, files, renders)
    for name in ("texel16", "texel8"):
        said = info[name]["console"]
        assert info[name]["prt"] and not [m for m in said if m.startswith(("error", "pageerror"))], said
        assert sorted(info[name]["info"]["sources"]) == ["texel", "texture"], info[name]["info"]
    results = {}
    for i, (f, t) in enumerate((f, t) for f in files for t in range(len(turns))):
        file = tmp_path / f"{f['name']}_{t}.f32"
        images[i].astype(np.float32).tofile(file)
        results[(f["name"], angles[t])] = _compare(references[t], file, WIDTH, HEIGHT)
    with capsys.disabled():
        for (name, angle), r in results.items():
            print(
                f"\nplugin vs render_view, {name} at {angle} rad: mean {100 * r['mean']:.3f} %, "
                f"p99 {100 * r['p99']:.3f} %, coverage {100 * r['coverage']:.3f} %"
            )
    for r in results.values():
        assert r["drawn"] > 0.3 and r["mean"] < MEAN_TOLERANCE and r["p99"] < P99_TOLERANCE, results
    # Not a constant: the ground's pixels vary (Suzanne's shadow, the sky's gradient) as render_view's.
    reference = references[0]
    ground = reference[..., 3] > 0
    assert np.ptp(reference[..., 1][ground]) > 0.5 * reference[..., 1][ground].mean()
