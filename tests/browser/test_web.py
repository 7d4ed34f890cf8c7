"""The web viewer (docs/export.md): its JS SH rotation against the core, its build, its image against api.render_view."""

import numpy as np
import pytest
from helpers.web import (
    COVERAGE_TOLERANCE,
    MEAN_TOLERANCE,
    P99_TOLERANCE,
    _compare,
    _run_viewer,
    _tool,
    _turns_and_references,
    coloured_material,
)

# --- the viewer in headless Chromium ------------------------------------------------------------


@pytest.mark.gpu
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
        material = coloured_material(bpy, "PRT test clay", (0.9, 0.35, 0.2))
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


@pytest.mark.gpu
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
