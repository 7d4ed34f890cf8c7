"""The three.js plugin's Principled specular (sky, split-sum table, occlusion, split lights' highlights) against api.render_view with Specular on."""

import numpy as np
import pytest
from helpers.material_scenes import glossy_scene
from helpers.specular_scenes import object_masks
from helpers.web import float_renders, run_plugin_page

pytestmark = pytest.mark.gpu  # (render_view draws the references with the GPU)

WIDTH, HEIGHT = 320, 160


def _plugin_images(browser_tools, tmp_path, files, renders, release=()):
    summary = run_plugin_page(browser_tools, tmp_path, files, renders, timeout=1200, release=release)
    return summary, float_renders(summary, HEIGHT, WIDTH)


def test_the_plugin_draws_principled_specular_as_render_view(bpy_module, addon, browser_tools, tmp_path, capsys):
    import bpy

    from prt_addon import api
    from prt_addon.blender.display import offscreen

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    assert offscreen.ensure_gpu()
    objects, _cam = glossy_scene(bpy, scene)
    api.project_world(order=8)
    api.bake(list(objects.values()), order=8, samples=64)
    glb = api.export_gltf(str(tmp_path / "glossy.glb"), environment_size=0)
    reference = api.render_view(scene, WIDTH, HEIGHT)
    masks = object_masks(bpy, scene, objects)
    scene.prt_display.specular = False
    diffuse_reference = api.render_view(scene, WIDTH, HEIGHT)
    files = [
        {"name": "specular", "glb": glb},
        {"name": "diffuse", "glb": glb, "options": {"specular": False}},
    ]
    renders = [{"name": f["name"], "width": WIDTH, "height": HEIGHT} for f in files]
    # Drawn first from another camera: the occlusion pass (drawn when the view moves) must follow
    # the view back to the file's camera.
    elsewhere = {"fov": 40, "position": [4.0, 3.0, 5.0], "target": [0.0, 0.0, 0.0]}
    renders.insert(0, {"name": "specular", "width": WIDTH, "height": HEIGHT, "camera": elsewhere})
    summary, (moved, glossy, diffuse) = _plugin_images(browser_tools, tmp_path, files, renders, ["specular", "diffuse"])
    info = summary["files"]
    assert np.abs(moved - glossy).max() > 0.1  # (another view)
    for f in files:
        said = info[f["name"]]["console"]
        assert info[f["name"]]["prt"] and not [m for m in said if m.startswith(("error", "pageerror"))], said

    def error(image, ref, mask):
        return float(np.abs(image[..., :3] - ref[..., :3])[mask].mean() / ref[..., :3][mask].mean())

    results = {
        name: {
            "specular": error(glossy, reference, mask),
            "diffuse_only": error(diffuse, diffuse_reference, mask),
            "plugin_diffuse_vs_specular_reference": error(diffuse, reference, mask),
            "pixels": int(mask.sum()),
        }
        for name, mask in masks.items()
    }
    with capsys.disabled():
        print(f"\nlights {info['specular']['info']['lights']}, views {len(info['specular']['info']['views'])}")
        for name, r in results.items():
            print(
                f"{name}: specular {100 * r['specular']:.3f} %, diffuse only {100 * r['diffuse_only']:.3f} % "
                f"(diffuse against the specular reference {100 * r['plugin_diffuse_vs_specular_reference']:.1f} %), "
                f"{r['pixels']} pixels"
            )
    # Bounds: the spheres came out at 0.04-0.16 % (the same GLSL on two rasterisers, float16 sky
    # texels); the ground's 1.2-1.4 % is its diffuse shadow edges (the diffuse-only draw shows the
    # same there), not the specular.
    for name, r in results.items():
        assert r["pixels"] > 100
        bound = 0.02 if name == "ground" else 0.005
        assert r["specular"] < bound, results
    for name in ("r0.3_m1", "r0.6_m1"):  # the metals without specular are far off
        assert results[name]["plugin_diffuse_vs_specular_reference"] > 0.5, results
    # Released as an app does (the plugin's dispose(), then the scene's own geometries, materials
    # and textures), the files leave the renderer holding what it held before they were loaded:
    # the occlusion pass's points, the relight targets, the shadow maps and the shared sky and
    # split-sum table included.
    assert summary["released"]["diffuse"] == summary["memory"], summary
