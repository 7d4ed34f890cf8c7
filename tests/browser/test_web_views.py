"""The export's shadow views (PRT_lighting.lights[].views) and the web viewer drawing a wide light through them."""

import pytest
from helpers.web import (
    COVERAGE_TOLERANCE,
    MEAN_TOLERANCE,
    P99_TOLERANCE,
    _compare,
    _export,
    _lights,
    _run_viewer,
    _turns_and_references,
)

pytestmark = pytest.mark.gpu

ANGLES = [0.0, 2.1]


def test_viewer_draws_a_wide_light_as_render_view(demo_scene, browser_tools, tmp_path, capsys):
    """With a wide light, a sun and a disc light, the viewer draws the file's 18 views (16 wide
    maps) and its image is api.render_view's at two lighting rotations, to the split-lights test's
    tolerances. The same file without `views` (a file from before them) still loads and draws one
    view per light, which differs visibly from render_view where the wide light's shadow falls."""
    from prt_addon.blender.export import glb
    from prt_addon.blender.scene import lighting

    scene = demo_scene
    width, height = 480, 360
    path, _world = _export(scene, tmp_path / "wide.glb", _lights())
    lighting.set_lights_override(scene, _lights())
    try:
        turns, references = _turns_and_references(scene, ANGLES, width, height)
    finally:
        lighting.set_lights_override(scene, None)
    document, chunks = glb.read(path)
    for light in document["scenes"][0]["extras"]["PRT_lighting"]["lights"]:
        del light["views"]
    old = str(tmp_path / "old.glb")
    glb.write(old, document, chunks)
    job = {"html": browser_tools["html"], "width": width, "height": height, "turns": turns}
    summaries = {
        name: _run_viewer(browser_tools, dict(job, glb=file, out=str(tmp_path / name)), tmp_path)
        for name, file in (("views", path), ("old", old))
    }
    views = summaries["views"]["info"]["views"]
    assert [(v["light"], v["wide"], v["samples"]) for v in views] == [(0, True, 1)] * 16 + [
        (1, False, 16),
        (2, False, 1),
    ]
    assert [(v["light"], v["wide"]) for v in summaries["old"]["info"]["views"]] == [(0, False), (1, False), (2, False)]
    results = {
        name: [_compare(ref, image["file"], width, height) for ref, image in zip(references, summary["images"])]
        for name, summary in summaries.items()
    }
    with capsys.disabled():
        for name, rows in results.items():
            for angle, r in zip(ANGLES, rows):
                print(
                    f"\nwide light, {name} file: rotation {angle:.1f} rad: mean {100 * r['mean']:.3f} %, "
                    f"p99 {100 * r['p99']:.3f} %, coverage {100 * r['coverage']:.3f} %"
                )
    for r in results["views"]:
        assert r["drawn"] > 0.3
        assert r["mean"] < MEAN_TOLERANCE and r["p99"] < P99_TOLERANCE, results
        assert r["coverage"] < COVERAGE_TOLERANCE, results
    for new, r in zip(results["views"], results["old"]):
        assert r["p99"] > 3 * new["p99"], results
