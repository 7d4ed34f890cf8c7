"""The three.js plugin keeps the glTF material's base colour texture: per pixel, on its UV channel, through its transform, sRGB decoded."""

import copy

import numpy as np
import pytest
from helpers.material_scenes import (
    CAMERA,
    PAINT,
    paint_box,
    pixel_map,
    quadrant_png,
    texture_colour,
    textured_scene,
)
from helpers.shadow_scenes import cap_light
from helpers.web import float_renders, run_plugin_page

WIDTH, HEIGHT = 320, 240
# Mean relative error allowed between the textured image and the white one times the texture's
# colour. Inside a quadrant every texel is the same, so the bilinear lookup returns that texel,
# and the product is the same float product either way: what is left is the GPU's sRGB decoding
# of 8-bit values against the exact curve (below 0.1 % of the value) and float32 rounding.
MEAN_TOLERANCE = 0.002
EDGE_TEXELS = 1.5  # pixels whose lookup is within this of a quadrant's edge mix two colours: left out


def _plugin_images(browser_tools, tmp_path, files, renders):
    summary = run_plugin_page(browser_tools, tmp_path, files, renders, timeout=900)
    return summary["files"], float_renders(summary, HEIGHT, WIDTH)


def _with_transform(path, out, offset):
    """A copy of the .glb whose base colour texture has KHR_texture_transform's offset."""
    from prt_addon.blender.export import glb

    document, chunks = glb.read(path)
    document = copy.deepcopy(document)
    material = next(m for m in document["materials"] if m.get("name") == "textured")
    info = material["pbrMetallicRoughness"]["baseColorTexture"]
    info.setdefault("extensions", {})["KHR_texture_transform"] = {"offset": list(offset)}
    document.setdefault("extensionsUsed", []).append("KHR_texture_transform")
    glb.write(out, document, chunks)
    return str(out)


@pytest.fixture(scope="module")
def textured_files(bpy_module, addon, tmp_path_factory):
    """The textured scene baked (order 4, one split sun) and exported three times: with the
    quadrant texture, with a white one in its place, and then with the box's colour attribute as
    its base colour."""
    import bpy

    from prt_addon import api
    from prt_addon.blender.scene import lighting

    folder = tmp_path_factory.mktemp("materials")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    ground, box, tex = textured_scene(bpy, scene, quadrant_png(folder / "quadrants.png"))
    api.project_world(order=4, split_lights=False)
    sun, _ = cap_light((0.5, -0.4, 0.75), np.radians(1.0))
    lighting.set_lights_override(scene, [sun])
    try:
        api.bake([ground, box], order=4, samples=64)
        textured = api.export_gltf(str(folder / "textured.glb"), environment_size=0)
        tex.image = bpy.data.images.load(quadrant_png(folder / "white.png", white=True))
        white = api.export_gltf(str(folder / "white.glb"), environment_size=0)
        paint_box(bpy, box)
        painted = api.export_gltf(str(folder / "painted.glb"), environment_size=0)
    finally:
        lighting.set_lights_override(scene, None)
    return {"textured": textured, "white": white, "painted": painted}


def test_the_base_colour_texture_multiplies_each_pixel(textured_files, browser_tools, tmp_path, capsys):
    """Textured = white x the texture's colour where each pixel lands on the ground (its UV from
    the camera's rays, not from the page), the quadrants where they should be; the untextured box
    unchanged; a texture transform's offset moves the lookup; a mirrored expectation fails; the
    box's vertex colours multiply it when its material uses them."""
    shifted = _with_transform(textured_files["textured"], tmp_path / "shifted.glb", (0.5, 0.25))
    files = [
        {"name": "textured", "glb": textured_files["textured"]},
        {"name": "white", "glb": textured_files["white"]},
        {"name": "shifted", "glb": shifted},
        {"name": "painted", "glb": textured_files["painted"]},
    ]
    # (the diffuse only: a Principled dielectric's specular is added, not multiplied by the texture)
    files = [dict(f, options={"specular": False}) for f in files]
    renders = [{"name": f["name"], "width": WIDTH, "height": HEIGHT, "camera": CAMERA} for f in files]
    info, (textured, white, moved, painted) = _plugin_images(browser_tools, tmp_path, files, renders)
    for f in files:
        said = info[f["name"]]["console"]
        assert info[f["name"]]["prt"] and not [m for m in said if m.startswith(("error", "pageerror"))], said
        assert info[f["name"]]["info"]["lights"] == 1, info[f["name"]]["info"]
    uv, on_box = pixel_map(WIDTH, HEIGHT)
    ground = ~np.isnan(uv[..., 0]) & ~on_box
    # (the box's silhouette and the ground's rim: a pixel either way)
    near_box = on_box | np.roll(on_box, 1, 0) | np.roll(on_box, -1, 0) | np.roll(on_box, 1, 1) | np.roll(on_box, -1, 1)

    def error(image, expected, mask):
        relative = np.abs(image[..., :3] - expected) / np.maximum(expected, 1e-6)
        return float(relative[mask].mean())

    results = {}
    for name, image, offset in (("textured", textured, (0.0, 0.0)), ("shifted", moved, (0.5, -0.25))):
        colour, edge = texture_colour(np.nan_to_num(uv), offset)
        mask = ground & ~near_box & (edge > EDGE_TEXELS)
        expected = white[..., :3] * colour
        mirrored, _ = texture_colour(np.nan_to_num(np.stack([1 - uv[..., 0], uv[..., 1]], -1)), offset)
        results[name] = {
            "mean": error(image, expected, mask),
            "mirrored": error(image, white[..., :3] * mirrored, mask),
            "pixels": int(mask.sum()),
        }
    box = on_box & np.roll(on_box, 1, 0) & np.roll(on_box, -1, 0) & np.roll(on_box, 1, 1) & np.roll(on_box, -1, 1)
    box_error = error(textured, white[..., :3], box)
    # The painted box: its vertex colours times white's grey base colour (0.6) where that was 0.6.
    paint_error = error(painted, white[..., :3] * np.array(PAINT) / 0.6, box)
    unpainted = error(painted, white[..., :3], box)
    with capsys.disabled():
        for name, r in results.items():
            print(
                f"\n{name}: mean relative error {100 * r['mean']:.4f} % over {r['pixels']} ground pixels "
                f"(mirrored in u: {100 * r['mirrored']:.1f} %)"
            )
        print(f"untextured box: {100 * box_error:.5f} % over {int(box.sum())} pixels")
        print(
            f"painted box against its colour attribute: {100 * paint_error:.4f} % (unpainted {100 * unpainted:.1f} %)"
        )
    for r in results.values():
        assert r["pixels"] > 0.3 * WIDTH * HEIGHT, results
        assert r["mean"] < MEAN_TOLERANCE and r["mirrored"] > 0.3, results
    assert box.sum() > 500 and box_error < 1e-6
    assert info["painted"]["meshes"] and paint_error < MEAN_TOLERANCE and unpainted > 0.3
    # The white image is lit, not flat: the box's shadow and the sun make the ground vary.
    lit = white[..., 1][ground & ~near_box]
    assert np.ptp(lit) > 0.3 * lit.mean()
