"""Public Python API of PRT Lighting (stable names; documented in docs/api.md).

The maths functions are pure numpy and work without Blender. Functions that take Blender data
import the Blender layer only when called.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .core.sh import basis as _sh, projection as _projection, rotation as _rotation
from .core.sh.directions import make_directions as make_directions

if TYPE_CHECKING:  # Blender types, only for the annotations
    import bpy

    from .blender.bake.settings import BakeReport


def sh_basis(directions: npt.ArrayLike, order: int) -> np.ndarray:
    """Real orthonormal SH basis (no Condon-Shortley phase, Z up) at directions: (N, order**2)."""
    return _sh.sh_basis(directions, order)


def project_equirect(pixels: npt.ArrayLike, order: int) -> np.ndarray:
    """(H, W, C) equirectangular image, row 0 at the bottom as Image.pixels -> (order**2, 3).

    NaN/Inf values are set to 0 and negative values clamped to 0; use
    prt_addon.core.sh.projection.project_equirect to also get the counts.
    """
    coeffs, _report = _projection.project_equirect(pixels, order)
    return coeffs


def rotation_matrix(rotation: npt.ArrayLike, order: int) -> np.ndarray:
    """(order**2, order**2) matrix M such that M @ c are the coefficients of f(R^-1 w).

    `rotation` is a 3x3 rotation matrix (anything np.asarray turns into one, e.g. a
    mathutils.Matrix.to_3x3()).
    """
    return _rotation.rotation_matrix(np.asarray(rotation, dtype=np.float64), order)


def project_world(
    scene: bpy.types.Scene | None = None,
    order: int | None = None,
    split_lights: bool | None = None,
    threshold: float | None = None,
    max_lights: int | None = None,
) -> np.ndarray:
    """Project scene.world (default: the context scene) into SH, store it on the scene and
    return the world-space coefficients (order**2, 3). order=None uses scene.prt_world.order.

    split_lights: True/False splits (or not) the world's compact bright sources off as disc
    lights for this call (world_lights reads them), None uses scene.prt_world.split_lights;
    threshold (luminance, 0: automatic) and max_lights (0 to 8) likewise override
    auto_threshold / light_threshold and max_lights for this call. The settings themselves are not changed.

    Raises ValueError (prt_addon.blender.world.nodes.WorldError) with a clear message when the world
    cannot be projected or an argument is out of range; the stored lighting is then left unchanged.
    """
    import bpy

    from .blender.world import projection as _world

    scene = bpy.context.scene if scene is None else scene
    result = _world.project_and_store(
        scene, order, split_lights=split_lights, threshold=threshold, max_lights=max_lights
    )
    return result.coeffs.copy()


def world_lights(scene: bpy.types.Scene | None = None) -> list[dict[str, Any]]:
    """The split lights of the scene in world space, with the Mapping rotation now: a list of
    {"direction": (3,) unit array, "power": (3,) RGB array (irradiance on a surface facing the
    light, Background strength included), "angle": disc radius in radians, "samples": (k, 3)
    unit directions over the light's own texels or None, "weights": (k,) their shares of its
    power (sum 1) or None}, strongest first; [] when the projection has none (split off, a
    colour world, no bright source). The shading uses the samples when there are some."""
    import bpy

    from .blender.scene import lighting as _lighting

    lights = _lighting.world_lights(bpy.context.scene if scene is None else scene)
    return [
        {
            "direction": light.direction.copy(),
            "power": light.power.copy(),
            "angle": float(light.angle),
            "samples": None if light.samples is None else light.samples.copy(),
            "weights": None if light.weights is None else light.weights.copy(),
        }
        for light in lights
    ]


def world_lighting(scene: bpy.types.Scene | None = None) -> np.ndarray | None:
    """World-space SH lighting (n*n, 3) stored on the scene for its current Mapping rotation,
    or None if nothing was projected."""
    import bpy

    from .blender.world import projection as _world

    return _world.current_world_coeffs(bpy.context.scene if scene is None else scene)


def shade(obj: bpy.types.Object, scene: bpy.types.Scene | None = None, side: str = "FRONT") -> np.ndarray:
    """Per-element radiance (elements, 3) for a white surface (albedo excluded):
    max(sum_i L_i t_i, 0) per channel with the scene's lighting rotated into obj's local frame,
    plus for each split light power / pi * max(0, n . s) * V, V the fraction of its disc that
    rays from the element see unoccluded by the scene's visible meshes. One row per vertex for a
    POINT-domain bake (per face corner for CORNER), the quantity Cycles' DIFFUSE bake with
    pass_filter={'DIRECT'} writes. side="BACK": the back side of an open mesh (one with boundary
    edges) baked per vertex or corner, what that bake writes for the mesh with its normals
    flipped; a ValueError for a bake without a back side."""
    from .blender.scene import lighting as _lighting

    return _lighting.shade(obj, scene, side)


def render_view(
    scene: bpy.types.Scene | None = None,
    width: int | None = None,
    height: int | None = None,
    camera: bpy.types.Object | None = None,
    display: bool = False,
) -> np.ndarray:
    """(H, W, 4) float32 image of the baked objects drawn with the PRT shader from the scene
    camera, offscreen, top row first (alpha 0 where nothing is drawn). display=False: linear
    radiance. display=True: exactly as the viewport overlay draws it, display-referred (0..1):
    times 2**exposure, through the scene's view transform, look, gamma and display device."""
    from .blender.display import offscreen as _offscreen

    return _offscreen.render_view(scene, width, height, camera, display=display)


def save_png(
    image: npt.ArrayLike, path: str, scene: bpy.types.Scene | None = None, background: Sequence[float] | None = None
) -> str:
    """Save an image from render_view as PNG through the scene's colour management."""
    from .blender.display import offscreen as _offscreen

    return _offscreen.save_png(image, path, scene, background)


def bake(
    objects: bpy.types.Object | Sequence[bpy.types.Object],
    order: int = 4,
    samples: int = 256,
    shadows: bool = True,
    backend: str = "AUTO",
    direction_set: str = "FIBONACCI",
    seed: int = 0,
    self_shadow_only: bool = False,
    progress: Callable[[float, str], None] | None = None,
    bounces: int = 0,
    target: str = "VERTICES",
    uv_map: str | None = None,
    resolution: int | None = None,
    **options: Any,
) -> BakeReport:
    """Bake diffuse SH transfer into mesh objects (docs/bake.md, storage: docs/storage.md).

    objects: an Object or a list; meshes that cannot be baked are listed in report.skipped.
    backend: 'AUTO' (Embree when embreex imports, else BVH tree), 'EMBREE' or 'BVHTREE'.
    direction_set: 'FIBONACCI', 'STRATIFIED' or 'UNIFORM' (seeded by `seed`).
    self_shadow_only: only each object itself occludes (else every visible mesh in the scene).
    bounces: diffuse reflections between the world and the receiver, 0 to 8 (the count of
    Cycles' Light Paths > Max Bounces > Diffuse); 0 is the direct transfer. Bounced light takes
    each surface's albedo from its material (docs/bake.md, "Interreflection").
    target: 'VERTICES' (FLOAT_COLOR attributes per vertex or face corner) or 'TEXELS' (a float
    image per object, sampled through a lightmap UV map: docs/texels.md).
    uv_map (TEXELS): the UV map to bake into; None: the first UV map whose name contains
    "lightmap", else a new UV map "PRT Lightmap" made by Smart UV Project (the others untouched).
    resolution (TEXELS): texels per side for every object, or None for options' texel_density
    (texels per metre of surface, default 20).
    progress: optional callable(fraction, text) after each chunk; an exception raised there
    aborts the bake and leaves every mesh unchanged.
    options: cull=True (skip rays where nothing can occlude), depsgraph, chunk_rays, threads
    (None, the default: Blender's own setting, Render Properties > Performance > Threads),
    texel_density, adaptive (TEXELS: interpolate 4 x 4 blocks whose corners agree within this
    relative tolerance, default 0.05; 0 traces every texel: docs/texels.md, "Adaptive sampling").

    Returns a BakeReport (seconds, rays_traced, rays_skipped and the reasons, backend,
    error_estimate, error_estimate_relative, objects, skipped). Raises ValueError (BakeError)
    with a clear message when nothing can be baked (empty selection, no mesh with faces, ...).
    No undo step is pushed: use the operator prt.bake_transfer for that.
    """
    from .blender.bake import job as _job

    return _job.bake(
        objects,
        order=order,
        samples=samples,
        shadows=shadows,
        backend=backend,
        direction_set=direction_set,
        seed=seed,
        self_shadow_only=self_shadow_only,
        progress=progress,
        bounces=bounces,
        target=target,
        uv_map=uv_map,
        resolution=resolution,
        **options,
    )


def estimate_bake(
    objects: bpy.types.Object | Sequence[bpy.types.Object],
    order: int = 4,
    samples: int = 256,
    bounces: int = 0,
    target: str = "VERTICES",
    resolution: int | None = None,
    **options: Any,
) -> dict[str, Any]:
    """What bake() with these arguments would take, before it runs (nothing is traced): a dict
    with elements (points baked), bounce_elements, rays (candidate rays), seconds, bytes (peak
    memory; with bounces an upper bound), available (the machine's available memory now),
    threads and fits (bytes within 90 % of available: else bake() refuses with BakeError).
    options: shadows, self_shadow_only, direction_set, threads, texel_density (docs/bake.md, "Estimates")."""
    from .blender.bake import estimate as _estimate
    from .blender.bake.settings import BakeSettings

    if objects is not None and not isinstance(objects, (list, tuple)):
        objects = [objects]
    settings = BakeSettings(
        order=order, samples=samples, bounces=bounces, target=target, resolution=resolution, **options
    )
    return _estimate.estimate(list(objects or []), settings).as_dict()


def bake_status(obj: bpy.types.Object, reason: bool = False) -> str | tuple[str, str]:
    """'fresh', 'stale' (the topology changed since the bake) or 'none' for an object;
    with reason=True, a (status, explanation) pair."""
    from .blender.bake import job as _job

    state, why = _job.status(obj)
    return (state, why) if reason else state


def export_gltf(
    path: str,
    objects: Sequence[bpy.types.Object] | None = None,
    scene: bpy.types.Scene | None = None,
    environment_size: int = 128,
    transfer: str = "snorm16",
) -> str:
    """Write the baked objects (default: every baked mesh of the scene) and the scene's lighting
    to a binary glTF file `path` (.glb) through Blender's glTF exporter; returns the path.
    The transfer, rotated into glTF's Y-up frame, is in the attributes _PRT_T0, _PRT_T1, ...,
    the metadata and the lighting in the extras "PRT_lighting" (docs/export.md). The user's data,
    selection and active object are left as they were. Raises ValueError with a clear message
    (nothing baked, a stale bake, no lighting, a path that cannot be written); no file is left.
    environment_size: the face size (a power of two up to 256) of the world's prefiltered cube map
    in EXT_lights_image_based, for viewers without PRT; 0 leaves the extension out.
    transfer: "snorm16" (16-bit normalised with a scale and offset per component, the default),
    "snorm8" or "float32" (docs/export.md)."""
    from .blender.export import gltf as _gltf

    return _gltf.export_gltf(path, objects, scene, environment_size, transfer)
