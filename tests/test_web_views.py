"""The export's shadow views (PRT_lighting.lights[].views) and the web viewer drawing a wide light through them."""

import dataclasses

import numpy as np
import pytest
from test_web import (
    COVERAGE_TOLERANCE,
    MEAN_TOLERANCE,
    P99_TOLERANCE,
    _compare,
    _run_viewer,
    _turns_and_references,
    browser_tools,  # noqa: F401
    demo_scene,  # noqa: F401
)
from test_wide_shadows import cap_light

pytestmark = [pytest.mark.blender, pytest.mark.gpu]

ANGLES = [0.0, 2.1]


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


def _file_lights(path):
    from prt_addon.blender.export import glb

    document, _chunks = glb.read(path)
    return document["scenes"][0]["extras"]["PRT_lighting"]["lights"]


def test_the_export_writes_each_lights_shadow_views(demo_scene, tmp_path):  # noqa: F811
    """Each light's `views` are core.lights.shadow_views' of the scene's lights at the full budget, in the
    glTF frame: every sample of a light in exactly one of its views, a view's direction the
    normalised weighted mean of its samples (a wide light's) or the light's direction (a compact
    one's), its angle sqrt(m / k) of the light's shadow angle; a light without samples has one
    view with `samples` null."""
    from prt_addon.blender.export.gltf import BLENDER_TO_GLTF
    from prt_addon.core.lights.samples import shadow_angle
    from prt_addon.core.lights.shadow_views import shadow_views

    path, world = _export(demo_scene, tmp_path / "views.glb", _lights())
    lights = _file_lights(path)
    assert len(lights) == 3
    expected = shadow_views(world)
    written = [(index, view) for index, light in enumerate(lights) for view in light["views"]]
    assert len(written) == len(expected) == 16 + 1 + 1
    for (index, view), want in zip(written, expected, strict=True):
        assert index == want.light
        assert view["wide"] == want.wide
        np.testing.assert_allclose(view["direction"], BLENDER_TO_GLTF @ want.direction, atol=1e-15)
        assert view["angle"] == pytest.approx(want.angle, rel=1e-15)
        if view["samples"] is None:
            np.testing.assert_allclose(BLENDER_TO_GLTF @ want.samples[0], view["direction"], atol=1e-15)
            continue
        samples = np.array(lights[index]["samples"])[view["samples"]]
        weights = np.array(lights[index]["weights"])[view["samples"]]
        np.testing.assert_allclose(samples, want.samples @ BLENDER_TO_GLTF.T, atol=1e-15)
        np.testing.assert_allclose(weights / np.sum(lights[index]["weights"]), want.weights, rtol=1e-12)
    # Independently of shadow_views: what the views mean in the file's own terms.
    for light, source in zip(lights, world, strict=True):
        k = len(light["samples"]) if light["samples"] is not None else 1
        if light["samples"] is None:
            assert [v["samples"] for v in light["views"]] == [None]
            continue
        indices = np.concatenate([v["samples"] for v in light["views"]])
        assert sorted(indices.tolist()) == list(range(k))
        for view in light["views"]:
            m = len(view["samples"])
            samples = np.array(light["samples"])[view["samples"]]
            weights = np.array(light["weights"])[view["samples"]]
            mean = weights @ samples
            centre = mean / np.linalg.norm(mean) if view["wide"] else np.array(light["direction"])
            np.testing.assert_allclose(view["direction"], centre, atol=1e-12)
            share = np.sqrt(m / k) if view["wide"] else 1.0
            assert view["angle"] == pytest.approx(shadow_angle(source) * share, rel=1e-12)
    assert [v["wide"] for v in lights[0]["views"]] == [True] * 16
    assert [len(v["samples"]) for v in lights[0]["views"]] == [1] * 16


@pytest.mark.browser
def test_viewer_draws_a_wide_light_as_render_view(demo_scene, browser_tools, tmp_path, capsys):  # noqa: F811
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
