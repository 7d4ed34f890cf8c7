"""The web viewer draws a bounced bake (colour bounce, split lights' SH) as api.render_view does."""

import numpy as np
import pytest
from helpers.web import (
    COVERAGE_TOLERANCE,
    MEAN_TOLERANCE,
    P99_TOLERANCE,
    _compare,
    _run_viewer,
    _turns_and_references,
    coloured_material,
)


@pytest.mark.gpu
def test_viewer_draws_a_bounced_bake(demo_scene, browser_tools, tmp_path, capsys):
    import bpy

    from prt_addon import api

    scene = demo_scene
    suzanne, ground = scene.objects["Suzanne"], scene.objects["Ground"]
    material = coloured_material(bpy, "PRT test green ground", (0.2, 0.7, 0.3))
    ground.data.materials.append(material)
    width, height = 320, 240
    try:
        report = api.bake([suzanne, ground], order=8, samples=64, bounces=2)
        assert report.bounce_channels == 3
        glb = api.export_gltf(str(tmp_path / "bounced.glb"))
        turns, references = _turns_and_references(scene, [0.0, 2.1], width, height)
    finally:
        ground.data.materials.clear()
        bpy.data.materials.remove(material)
        api.bake([suzanne, ground], order=8, samples=64)  # the module's scene as the other tests expect
    job = {"html": browser_tools["html"], "glb": glb, "width": width, "height": height, "turns": turns}
    summary = _run_viewer(browser_tools, dict(job, out=str(tmp_path / "viewer")), tmp_path)
    results = [_compare(ref, image["file"], width, height) for ref, image in zip(references, summary["images"])]
    with capsys.disabled():
        for angle, r in zip([0.0, 2.1], results):
            print(f"\nbounced: rotation {angle:.1f} rad: mean {100 * r['mean']:.3f} %, p99 {100 * r['p99']:.3f} %")
    for r in results:
        assert r["mean"] < MEAN_TOLERANCE and r["p99"] < P99_TOLERANCE, results
        assert r["coverage"] < COVERAGE_TOLERANCE, results
    # The bounced light is visible: the direct-only image differs far more than the tolerance.
    api.bake([suzanne, ground], order=8, samples=64)
    plain = api.render_view(scene, width, height)
    drawn = references[0][..., 3] > 0
    assert np.abs(plain[..., :3] - references[0][..., :3])[drawn].mean() > 10 * MEAN_TOLERANCE * results[0]["level"]
