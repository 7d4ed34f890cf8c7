"""The export writes each light's shadow views (one per compact light, one per sample group of a wide one)."""

import numpy as np
import pytest
from helpers.web import (
    _export,
    _lights,
)


def _file_lights(path):
    from prt_addon.blender.export import glb

    document, _chunks = glb.read(path)
    return document["scenes"][0]["extras"]["PRT_lighting"]["lights"]


def test_the_export_writes_each_lights_shadow_views(demo_scene, tmp_path):
    """Each light's `views` are core.lights.shadow_views' of the scene's lights at the web viewer's full budget, in the
    glTF frame: every sample of a light in exactly one of its views, a view's direction the
    normalised weighted mean of its samples (a wide light's) or the light's direction (a compact
    one's), its angle sqrt(m / k) of the light's shadow angle; a light without samples has one
    view with `samples` null."""
    from prt_addon.blender.export.gltf import BLENDER_TO_GLTF, WEB_WIDE_VIEWS
    from prt_addon.core.lights.samples import shadow_angle
    from prt_addon.core.lights.shadow_views import shadow_views

    path, world = _export(demo_scene, tmp_path / "views.glb", _lights())
    lights = _file_lights(path)
    assert len(lights) == 3
    expected = shadow_views(world, max_wide_views=WEB_WIDE_VIEWS)
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
