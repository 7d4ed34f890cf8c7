"""Web fixtures: the node packages of Khronos' validator, Chromium and the built viewer, the demo scene baked."""

import os
import shutil
import subprocess

import pytest

from helpers.paths import ROOT
from helpers.web import _demo_module, _tool


@pytest.fixture(scope="session")
def validator_modules():
    if shutil.which("npm") is None or shutil.which("node") is None:
        pytest.skip("npm and node are needed for the Khronos glTF validator (install Node.js)")
    out = subprocess.run(
        ["bash", os.path.join(ROOT, "scripts", "setup_node.sh")], check=True, capture_output=True, text=True
    )
    return out.stdout.strip().splitlines()[-1]


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


TEXEL_RESOLUTION = 128  # the texel demo's ground: 4.7 cm texels


@pytest.fixture(scope="module")
def texel_demo_scene(bpy_module, addon):
    """The demo's scene projected at order 8, Suzanne baked per vertex and the ground per texel
    (TEXEL_RESOLUTION) into a second UV map "Lightmap" (TEXCOORD_1 in the glTF), without split lights."""
    from prt_addon import api
    from prt_addon.blender.scene import lighting

    scene = _demo_module().build_scene(_demo_module().bundled_hdri_path("forest"))
    api.project_world(order=8)
    ground = scene.objects["Ground"]
    ground.data.uv_layers.new(name="Lightmap")  # (a copy of UVMap, the grid's planar map)
    lighting.set_lights_override(scene, [])
    api.bake([scene.objects["Suzanne"]], order=8, samples=64)
    api.bake([ground], order=8, samples=64, target="TEXELS", uv_map="Lightmap", resolution=TEXEL_RESOLUTION)
    yield scene
    lighting.set_lights_override(scene, None)
