"""EXT_lights_image_based in the .glb: the world's GGX-prefiltered cube map and its irradiance SH.

Babylon.js's loader is the extension's reference, and these are its conventions (read from its
source, checked in tests/browser/test_babylon_ibl.py); docs/export.md is the contract:

* Babylon's glTF root node turns glTF's right-handed frame into its left-handed world by
  (x, y, z) -> (-x, y, z), and samples the cube map (WebGL's convention, core.ibl.prefilter) with
  world directions: so the cube frame is glTF's with x negated (BABYLON_FROM_GLTF).
* Each face image is uploaded flipped (texture row 0 = the image's bottom row): a PNG's top row
  is the face's t = +1 row.
* Its SH basis has the Condon-Shortley phase and is evaluated in that left-handed frame; the
  coefficients are irradiance (it divides them by pi for Lambertian radiance).
"""

import time

import numpy as np

from ...core.ibl import prefilter, rgbd_png
from ...core.sh import basis as sh
from ..world import nodes as _nodes
from ..world.pixels import NeedsRender, read_image_pixels, render_world

EXTENSION = "EXT_lights_image_based"
DEFAULT_SIZE = 128  # mip 0 face size; the chain goes down to 1 texel

# glTF direction -> Babylon world direction (its glTF root: scale (1, 1, -1), 180 degrees about Y).
BABYLON_FROM_GLTF = np.diag([-1.0, 1.0, 1.0])
# Blender (Z up) to glTF (Y up), as gltf.BLENDER_TO_GLTF.
_BLENDER_TO_GLTF = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])

# Band-l factor of the clamped cosine: irradiance E_lm = A_l L_lm.
COSINE_BANDS = np.array([np.pi] + [2.0 * np.pi / 3.0] * 3 + [np.pi / 4.0] * 5)
# Our coefficient i (glTF frame, no Condon-Shortley phase) -> Babylon's: (-1)^m for the phase,
# times -1 where y_i is odd in x (m = 1 in bands 1 and 2, m = -2) for the mirror x -> -x.
BABYLON_SIGNS = np.array([1.0, -1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0, 1.0])


def irradiance_coefficients(radiance):
    """(9, 3) irradiance coefficients in Babylon's convention of (n*n, 3) radiance SH in glTF's
    world frame (our basis); bands above 2 are dropped, missing ones are 0."""
    radiance = np.asarray(radiance, dtype=np.float64)
    padded = np.zeros((9, 3))
    m = min(9, radiance.shape[0])
    padded[:m] = radiance[:m]
    return padded * (COSINE_BANDS * BABYLON_SIGNS)[:, None]


def babylon_irradiance(coefficients, directions_gltf):
    """E at glTF directions (k, 3) from Babylon-convention coefficients (9, 3), evaluated as
    Babylon does (its basis, in its frame): for tests and docs."""
    b = np.asarray(directions_gltf, dtype=np.float64) @ BABYLON_FROM_GLTF.T
    basis = sh.sh_basis(b, 3) * np.array([1.0, -1.0, 1.0, -1.0, 1.0, -1.0, 1.0, -1.0, 1.0])
    return basis @ np.asarray(coefficients, dtype=np.float64)


def _radiance_source(scene, size):
    """(pixels (H, W, C) equirect or None, constant RGB or None, Q, strength): the world's
    radiance at Blender world direction w is strength image(Q^T w). Raises WorldError."""
    source = _nodes.analyse_world(scene)
    if source.kind == "COLOR":
        colour = np.clip(np.asarray(source.color, dtype=np.float64)[:3] * source.strength, 0.0, None)
        return None, colour, np.eye(3), 1.0
    if source.kind == "IMAGE":
        try:
            pixels = read_image_pixels(source.image)  # float32, not copied: large HDRIs stay cheap
            q = source.mapping.sh_rotation() if source.mapping is not None else np.eye(3)
            return pixels[:, :, :3], None, q, float(source.strength)
        except NeedsRender:
            pass
    # Cycles renders the world as the scene sees it: Mapping and strength included.
    return render_world(scene, 2 * size), None, np.eye(3), 1.0


def specular_mips(scene, size=DEFAULT_SIZE):
    """The prefiltered mips [(6, N, N, 3)] of the world (full, unsplit) in the cube frame."""
    size = prefilter.check_size(size)
    pixels, colour, q, strength = _radiance_source(scene, size)
    if pixels is None:
        cube = np.broadcast_to(colour, (6, size, size, 3)).copy()
    else:
        # cube frame -> glTF (BABYLON_FROM_GLTF is its own inverse) -> Blender -> image
        to_image = q.T @ _BLENDER_TO_GLTF.T @ BABYLON_FROM_GLTF
        cube = prefilter.radiance_cube(pixels, size, to_image) * strength
    return prefilter.prefilter_mips(cube)


def face_png(face):
    """PNG bytes of one (N, N, 3) face (rows in texture memory order): the RGBD image, rows
    flipped so that the picture's top row is t = +1, as Babylon uploads it."""
    return rgbd_png.png_bytes(rgbd_png.rgbd_encode(face[::-1]))


def environment(scene, world, size=DEFAULT_SIZE):
    """(light JSON without image indices, [[png bytes] * 6 per mip], figures) for the scene;
    world: gltf.world_extras(scene). Raises WorldError."""
    start = time.perf_counter()
    mips = specular_mips(scene, size)
    filtered = time.perf_counter()
    images = [[face_png(face) for face in mip] for mip in mips]
    # The full world: the PRT sky plus the split lights' SH (orders may differ: 9 terms of each).
    irradiance = irradiance_coefficients(world["coefficients"]) + irradiance_coefficients(world["lights_coefficients"])
    peak = max(float(m.max()) for m in mips)
    light = {
        "name": scene.world.name if scene.world is not None else "World",
        "intensity": 1.0,
        "rotation": [0.0, 0.0, 0.0, 1.0],
        "irradianceCoefficients": irradiance.tolist(),
        "specularImageSize": size,
        "extras": {
            "PRT_lighting": {
                "roughness": np.sqrt(prefilter.babylon_alphas(size)).tolist(),
                "clipped_above": rgbd_png.MAX_VALUE,
                "peak": peak,
            }
        },
    }
    figures = {
        "prefilter_seconds": filtered - start,
        "encode_seconds": time.perf_counter() - filtered,
        "bytes": sum(len(p) for mip in images for p in mip),
    }
    return light, images, figures


def write(document, chunks, light, images, chunk_bin):
    """Add the extension to a glTF JSON document and the PNGs to its BIN chunk (a list of
    (type, bytes), changed in place); every scene uses the light."""
    index = next((k for k, (kind, _p) in enumerate(chunks) if kind == chunk_bin), None)
    if index is None:
        chunks.insert(0, (chunk_bin, b""))
        document.setdefault("buffers", []).insert(0, {"byteLength": 0})
        for view in document.get("bufferViews", []):
            view["buffer"] += 1
        index = 0
    payload = bytearray(chunks[index][1])
    views = document.setdefault("bufferViews", [])
    gltf_images = document.setdefault("images", [])
    specular = []
    for k, mip in enumerate(images):
        row = []
        for f, png in enumerate(mip):
            payload += b"\0" * (-len(payload) % 4)
            views.append({"buffer": 0, "byteOffset": len(payload), "byteLength": len(png)})
            payload += png
            row.append(len(gltf_images))
            gltf_images.append(
                {
                    "name": f"PRT_environment_mip{k}_{prefilter.FACE_NAMES[f]}",
                    "mimeType": "image/png",
                    "bufferView": len(views) - 1,
                }
            )
        specular.append(row)
    chunks[index] = (chunk_bin, bytes(payload))
    document["buffers"][0]["byteLength"] = len(payload)
    light = dict(light, specularImages=specular)
    extension = document.setdefault("extensions", {}).setdefault(EXTENSION, {})
    extension.setdefault("lights", []).append(light)
    for gltf_scene in document.get("scenes", []):
        gltf_scene.setdefault("extensions", {})[EXTENSION] = {"light": len(extension["lights"]) - 1}
    used = document.setdefault("extensionsUsed", [])
    if EXTENSION not in used:
        used.append(EXTENSION)
