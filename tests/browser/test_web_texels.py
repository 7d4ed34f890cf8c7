"""The three.js plugin on a texel bake (the ground per texel, Suzanne per vertex) in headless Chromium, against api.render_view."""

import numpy as np
import pytest
from helpers.fixtures_web import TEXEL_RESOLUTION
from helpers.web import (
    MEAN_TOLERANCE,
    P99_TOLERANCE,
    _compare,
    _turns_and_references,
    coloured_material,
    float_renders,
    run_plugin_page,
)

pytestmark = pytest.mark.gpu  # (render_view draws the references with the GPU)

WIDTH, HEIGHT = 320, 240


def _plugin_images(browser_tools, tmp_path, files, renders):
    summary = run_plugin_page(browser_tools, tmp_path, files, renders, timeout=600)
    return summary["files"], float_renders(summary, HEIGHT, WIDTH)


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


def test_the_plugin_draws_a_bounced_texel_bake_as_render_view(texel_demo_scene, browser_tools, tmp_path, capsys):
    """A red Suzanne (per vertex) over the ground (per texel), both baked with 2 bounces: the
    ground's three bounce channels go out as their own planes, and the page's relight of them is
    render_view's image at two lighting rotations; the bounced light is visible (the direct-only
    image is far off)."""
    import bpy

    from prt_addon import api
    from prt_addon.blender.display import offscreen

    assert offscreen.ensure_gpu()
    scene = texel_demo_scene
    suzanne, ground = scene.objects["Suzanne"], scene.objects["Ground"]
    material = coloured_material(bpy, "PRT test red", (0.8, 0.15, 0.1))
    suzanne.data.materials.append(material)
    angles = [0.0, 2.1]
    texels = dict(target="TEXELS", uv_map="Lightmap", resolution=TEXEL_RESOLUTION)
    try:
        api.bake([suzanne], order=8, samples=64, bounces=2)
        report = api.bake([ground], order=8, samples=64, bounces=2, **texels)
        assert report.bounce_channels == 3
        glb = api.export_gltf(str(tmp_path / "bounced.glb"))
        turns, references = _turns_and_references(scene, angles, WIDTH, HEIGHT)
        api.bake([ground], order=8, samples=64, **texels)
        direct_ground = api.render_view(scene, WIDTH, HEIGHT)
    finally:
        suzanne.data.materials.clear()
        bpy.data.materials.remove(material)
        api.bake([suzanne], order=8, samples=64)  # the module's scene as the other tests expect
        api.bake([ground], order=8, samples=64, **texels)
    files = [{"name": "bounced", "glb": glb}]
    renders = [{"width": WIDTH, "height": HEIGHT, "name": "bounced", "turn": t} for t in turns]
    info, images = _plugin_images(browser_tools, tmp_path, files, renders)
    said = info["bounced"]["console"]
    assert info["bounced"]["prt"] and not [m for m in said if m.startswith(("error", "pageerror"))], said
    assert sorted(info["bounced"]["info"]["sources"]) == ["texel", "texture"], info["bounced"]["info"]
    results = []
    for t, image in enumerate(images):
        file = tmp_path / f"bounced_{t}.f32"
        image.astype(np.float32).tofile(file)
        results.append(_compare(references[t], file, WIDTH, HEIGHT))
    with capsys.disabled():
        for angle, r in zip(angles, results):
            print(
                f"\nplugin vs render_view, bounced texels at {angle} rad: mean {100 * r['mean']:.3f} %, "
                f"p99 {100 * r['p99']:.3f} %, coverage {100 * r['coverage']:.3f} %"
            )
    for r in results:
        assert r["drawn"] > 0.3 and r["mean"] < MEAN_TOLERANCE and r["p99"] < P99_TOLERANCE, results
    # The ground's bounced light shows: without it (Suzanne's bounces kept) the image is far off.
    drawn = references[0][..., 3] > 0
    gap = np.abs(direct_ground[..., :3] - references[0][..., :3]).max(axis=-1)[drawn].mean()
    assert gap > 10 * MEAN_TOLERANCE * references[0][..., :3][drawn].mean()


def test_the_plugin_draws_a_glossy_texel_bake_as_render_view(texel_demo_scene, browser_tools, tmp_path, capsys):
    """The ground per texel as a glossy metal with Specular on: its occlusion, the full transfer
    summed per pixel from its decoded tiles, is render_view's; Suzanne hides the sky's reflection
    from the ground about her (render_view without the texel occlusion is far off there)."""
    import bpy
    from helpers.specular_scenes import principled_material
    from helpers.texel_glossy_scene import without_texel_occlusion

    from prt_addon import api

    scene = texel_demo_scene
    ground = scene.objects["Ground"]
    material = principled_material(bpy, "PRT test glossy", (0.9, 0.9, 0.9), 0.3, 1.0)
    old_materials = list(ground.data.materials)
    ground.data.materials.clear()
    ground.data.materials.append(material)
    scene.prt_display.specular = True
    try:
        glb = api.export_gltf(str(tmp_path / "glossy_texels.glb"), environment_size=0)
        turns, references = _turns_and_references(scene, [0.0], WIDTH, HEIGHT)
        with without_texel_occlusion():
            unoccluded = api.render_view(scene, WIDTH, HEIGHT)
    finally:
        scene.prt_display.specular = False
        ground.data.materials.clear()
        for m in old_materials:
            ground.data.materials.append(m)
        bpy.data.materials.remove(material)
    files = [{"name": "glossy", "glb": glb}]
    info, images = _plugin_images(
        browser_tools, tmp_path, files, [dict(width=WIDTH, height=HEIGHT, name="glossy", turn=turns[0])]
    )
    said = info["glossy"]["console"]
    assert info["glossy"]["prt"] and not [m for m in said if m.startswith(("error", "pageerror"))], said
    file = tmp_path / "glossy.f32"
    images[0].astype(np.float32).tofile(file)
    result = _compare(references[0], file, WIDTH, HEIGHT)
    file_open = tmp_path / "unoccluded.f32"
    unoccluded.astype(np.float32).tofile(file_open)
    gap = _compare(references[0], file_open, WIDTH, HEIGHT)
    with capsys.disabled():
        print(
            f"\nplugin vs render_view, glossy texels: mean {100 * result['mean']:.3f} %, p99 {100 * result['p99']:.3f} %, "
            f"coverage {100 * result['coverage']:.3f} %; render_view without the texel occlusion: mean "
            f"{100 * gap['mean']:.3f} %, p99 {100 * gap['p99']:.3f} %"
        )
    assert result["drawn"] > 0.3 and result["mean"] < MEAN_TOLERANCE and result["p99"] < P99_TOLERANCE, result
    assert gap["p99"] > 5 * P99_TOLERANCE, gap
