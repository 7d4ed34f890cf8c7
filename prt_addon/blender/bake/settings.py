"""What a bake is asked to do and what it reports: settings, their checks, the report, backends."""

import os
from dataclasses import asdict, dataclass, field

import numpy as np

from ...core.sh.directions import KINDS
from ...core.trace import raytrace
from ...core.transfer import quadrature as transfer
from ...core.transfer.adaptive import TOLERANCE as ADAPTIVE
from ..scene.occluders import auto_backend

BACKENDS = ("AUTO", "EMBREE", "BVHTREE")
TARGETS = ("VERTICES", "TEXELS", "AUTO")
MAX_RESOLUTION = 4096


MAX_ORDER = 16
MIN_SAMPLES = 2  # the API's and the Samples property's minimum
MAX_BOUNCES = 8
ENCLOSED_SHARE = 0.6  # blocked share of the rays above the surfaces past which a bake without bounces proposes them


class BakeError(ValueError):
    """The bake cannot start (bad settings or nothing bakeable); the message says what to do."""


@dataclass
class BakeSettings:
    order: int = 4
    samples: int = 256
    direction_set: str = "FIBONACCI"
    seed: int = 0
    shadows: bool = True
    self_shadow_only: bool = False
    backend: str = "AUTO"
    cull: bool = True  # skip rays where nothing can occlude (False: trace them all, for tests)
    chunk_rays: int = transfer.CHUNK_RAYS
    threads: int = None  # None: Blender's own setting (Render > Performance > Threads)
    bounces: int = 0  # diffuse reflections between the world and the receiver (core.transfer.bounce)
    target: str = "VERTICES"  # where the transfer is stored: VERTICES (attributes) or TEXELS (an image)
    uv_map: str | None = None  # TEXELS: the UV map to bake into (None: a lightmap UV map, found or made)
    resolution: int | None = None  # TEXELS: texels per side (None: from texel_density)
    texel_density: float = 20.0  # TEXELS: texels per metre of surface when resolution is None
    adaptive: float = ADAPTIVE  # TEXELS: interpolate blocks whose corners agree within this (0: trace every texel)

    def validate(self):
        if (
            isinstance(self.order, bool)
            or not isinstance(self.order, (int, np.integer))
            or not 1 <= self.order <= MAX_ORDER
        ):
            raise BakeError(f"order must be an integer from 1 to {MAX_ORDER}, got {self.order!r}")
        if (
            isinstance(self.samples, bool)
            or not isinstance(self.samples, (int, np.integer))
            or self.samples < MIN_SAMPLES
        ):
            raise BakeError(f"samples must be an integer >= {MIN_SAMPLES}, got {self.samples!r}")
        self.direction_set = str(self.direction_set).upper()
        if self.direction_set not in KINDS:
            raise BakeError(f"direction_set must be one of {KINDS}, got {self.direction_set!r}")
        self.backend = str(self.backend).upper()
        if self.backend not in BACKENDS:
            raise BakeError(f"backend must be one of {BACKENDS}, got {self.backend!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise BakeError(f"seed must be an integer >= 0, got {self.seed!r}")
        if self.threads is not None and (
            isinstance(self.threads, bool) or not isinstance(self.threads, (int, np.integer)) or self.threads < 1
        ):
            raise BakeError(f"threads must be None (Blender's setting) or an integer >= 1, got {self.threads!r}")
        if (
            isinstance(self.bounces, bool)
            or not isinstance(self.bounces, (int, np.integer))
            or not 0 <= self.bounces <= MAX_BOUNCES
        ):
            raise BakeError(f"bounces must be an integer from 0 to {MAX_BOUNCES}, got {self.bounces!r}")
        if self.bounces and not self.shadows:
            raise BakeError("bounces need shadows: light only bounces off surfaces that block it (turn Shadows on)")
        if self.bounces and self.self_shadow_only:
            raise BakeError(
                "bounces need the whole scene's shadows: turn Self Shadow Only off (light bounces between objects)"
            )
        self._validate_target()
        self.order, self.samples, self.seed = int(self.order), int(self.samples), int(self.seed)
        self.bounces = int(self.bounces)
        return self

    def _validate_target(self):
        self.target = str(self.target).upper()
        if self.target not in TARGETS:
            raise BakeError(f"target must be one of {TARGETS}, got {self.target!r}")
        if self.target == "VERTICES":
            return
        res = self.resolution
        if res is not None and (isinstance(res, bool) or not isinstance(res, (int, np.integer)) or res < 1):
            raise BakeError(f"resolution must be None (from the texel density) or an integer >= 1, got {res!r}")
        if res is not None and res > MAX_RESOLUTION:
            raise BakeError(f"resolution {res} is above the largest lightmap, {MAX_RESOLUTION} texels per side")
        density = self.texel_density
        if isinstance(density, bool) or not isinstance(density, (int, float, np.number)) or not density > 0:
            raise BakeError(f"texel density must be a number of texels per metre > 0, got {density!r}")
        if not isinstance(self.adaptive, (int, float)) or not 0.0 <= self.adaptive <= 1.0:
            raise BakeError(f"adaptive must be a tolerance from 0 (off) to 1, got {self.adaptive!r}")
        if self.uv_map is not None and not isinstance(self.uv_map, str):
            raise BakeError(f"uv_map must be the name of a UV map or None, got {self.uv_map!r}")
        self.resolution = None if res is None else int(res)
        self.uv_map = self.uv_map or None


@dataclass
class BakeReport:
    ok: bool = False
    cancelled: bool = False
    message: str = ""
    objects: list = field(default_factory=list)
    skipped: list = field(default_factory=list)  # [(name, reason)] meshes (or convertible objects) not baked
    left_out: list = field(default_factory=list)  # [(name, reason)] objects with no geometry (cameras, lights)
    backend: str = "NONE"
    seconds: float = 0.0
    rays_traced: int = 0
    rays_skipped: int = 0
    rays_blocked: int = 0  # traced rays that hit a surface (most of them: an enclosed scene)
    estimate_seconds: float = 0.0  # what the estimate said before the bake (bake.estimate)
    estimate_bytes: int = 0
    skipped_below_horizon: int = 0
    skipped_unoccludable: int = 0
    skipped_shadows_off: int = 0
    points: int = 0
    error_estimate: float = 0.0
    error_estimate_relative: float = 0.0
    order: int = 0
    samples: int = 0
    direction_set: str = ""
    note: str = ""  # e.g. why the slower BVH tree fallback ran
    bounces: int = 0
    bounce_channels: int = 0  # 0: direct only; 1: grey albedos; 3: colour
    bounce_seconds: float = 0.0  # of the bounce passes (included in seconds)
    bounce_points: int = 0  # points of meshes that are not baked, traced only for the bounces
    albedo_notes: list = field(default_factory=list)  # e.g. textured colours taken as their mean
    target: str = "VERTICES"
    texels: int = 0  # covered texels of a texel bake
    texels_interpolated: int = 0  # of those, filled from agreeing block corners (adaptive)
    texel_notes: list = field(default_factory=list)  # the UV maps made, resolutions, faces not baked
    enclosed_share: float = 0.0  # the share of the front sides' rays above the surface that hit another surface

    @property
    def element(self):
        return "texel" if self.target == "TEXELS" else "vertex"

    def enclosed_note(self):
        """The sentence proposing bounces for an enclosed scene baked without them, or ''."""
        share = self.enclosed_share
        if self.bounces or share < ENCLOSED_SHARE:
            return ""
        return (
            f"{100.0 * share:.0f} % of the rays hit other surfaces (an enclosed scene): without bounces the light "
            "they reflect is missing and it comes out darker than Cycles; bake with Bounces 4, as Cycles"
        )

    @property
    def rays_per_second(self):
        return self.rays_traced / self.seconds if self.seconds > 0 else 0.0

    def as_dict(self):
        d = asdict(self)
        d["skipped"] = [list(s) for s in self.skipped]
        d["left_out"] = [list(s) for s in self.left_out]
        return d

    def headline(self):
        """One line: what was baked, how long, how many rays, how far from converged."""
        if not self.ok:
            return self.message or ("Bake cancelled" if self.cancelled else "Bake failed")
        return (
            f"Baked {len(self.objects)} object(s) in {self.seconds:.2f} s ({self.backend}), "
            f"{self.rays_traced:,} rays, error estimate "
            f"{100.0 * self.error_estimate_relative:.2f} %"
        )

    def report_lines(self):
        """The full report in words a user knows (the sidebar's Report panel)."""
        if not self.ok:
            lines = [self.headline()]
        else:
            engine = {"EMBREE": "Embree", "BVHTREE": "Blender's BVH tree"}.get(self.backend, "no ray needed tracing")
            lines = [
                f"Baked {len(self.objects)} object(s): {', '.join(self.objects)}",
                f"Time: {self.seconds:.2f} s, rays traced with {engine}",
                f"Order {self.order}: {self.order * self.order} numbers per {self.element}; "
                f"{self.samples} directions ({self.direction_set.lower()})",
                f"Rays traced: {self.rays_traced:,}",
                f"Rays skipped: {self.rays_skipped:,} ({self.skipped_below_horizon:,} below the surface, "
                f"{self.skipped_unoccludable:,} with nothing in the way, "
                f"{self.skipped_shadows_off:,} with shadows off)",
                f"Noise: about {100.0 * self.error_estimate_relative:.2f} % (the bake's own estimate "
                "of its sampling error; more samples lower it)",
            ]
            if self.bounces:
                colour = "in colour" if self.bounce_channels == 3 else "grey surfaces"
                extra = (
                    f"; {self.bounce_points:,} points of unbaked meshes traced for them" if self.bounce_points else ""
                )
                lines.append(f"Bounces: {self.bounces} ({colour}), {self.bounce_seconds:.2f} s, no extra rays{extra}")
            lines += self.albedo_notes + self.texel_notes + [self.enclosed_note()] * bool(self.enclosed_note())
        if self.note:
            lines.append(self.note)
        lines += [f"Skipped '{name}': {reason}" for name, reason in self.skipped]
        if self.left_out and self.ok:
            lines.append(f"Left out {len(self.left_out)} object(s) with no geometry to bake (cameras, lights, empties)")
        return lines

    def summary_lines(self):
        if not self.ok:
            lines = [self.message or ("Bake cancelled" if self.cancelled else "Bake failed")]
        else:
            lines = [
                f"Baked {len(self.objects)} object(s) in {self.seconds:.2f} s ({self.backend})",
                f"Order {self.order}, {self.samples} {self.direction_set.lower()} directions",
                f"Rays traced {self.rays_traced:,}, skipped {self.rays_skipped:,}",
                f"  below horizon {self.skipped_below_horizon:,}, nothing to occlude "
                f"{self.skipped_unoccludable:,}, shadows off {self.skipped_shadows_off:,}",
                f"Error estimate {self.error_estimate:.2e} ({100.0 * self.error_estimate_relative:.2f} % of |t|)",
            ]
        if self.note:
            lines.append(self.note)
        lines += [f"Skipped '{name}': {reason}" for name, reason in self.skipped]
        return lines


# Embree bake vs BVH tree bake throughput, measured by benchmarks/bench_bake.py (docs/bake.md).
FALLBACK_SLOWDOWN = "30 to 40"


def fallback_note():
    """The sentence shown when Auto falls back to the BVH tree because embreex does not import."""
    return (
        f"Embree (embreex) is not available on this system ({raytrace.EMBREE_IMPORT_ERROR}): "
        f"the slower BVH tree fallback was used (about {FALLBACK_SLOWDOWN} times slower, one thread)"
    )


def resolve_backend(requested):
    requested = str(requested).upper()
    if requested == "AUTO":
        return auto_backend()
    if requested == "EMBREE" and not raytrace.EMBREE_AVAILABLE:
        raise BakeError(
            f"the Embree backend is not available on this system ({raytrace.EMBREE_IMPORT_ERROR}): "
            "choose Auto or BVH Tree"
        )
    return requested


def blender_threads(scene):
    """The thread count of Blender's own setting (Render Properties > Performance > Threads):
    RenderSettings.threads reads as every logical core in Auto mode, else the Fixed number."""
    return max(1, int(scene.render.threads))


SAMPLES_PER_TEXEL = 4  # core.transfer.texels.SAMPLE_OFFSETS


BACK_SAMPLE, BACK_COEFF = 24, 18  # texel_memory's back side (fitted: docs/texels.md, "Back side")


def texel_memory(resolution, order, samples_per_texel=SAMPLES_PER_TEXEL, back=False):
    """Bytes a texel bake of one object at resolution x resolution texels takes at its peak (every
    texel covered): per sample, its position, normal, barycentrics and triangle and its ray
    origin and unit normal in the quadrature (145 bytes); per coefficient, the texels' float32
    sum (the samples add into it as they finish), the image with its gutter, seams and packed
    tiles (21 bytes). With `back` (an open mesh), its back side's normals and quadrature (BACK_SAMPLE
    bytes per sample) and its sum and image (BACK_COEFF per coefficient). Fitted to the peaks
    measured in docs/texels.md."""
    texels = int(resolution) ** 2
    per_texel = 145 * samples_per_texel + 21 * order * order
    if back:
        per_texel += BACK_SAMPLE * samples_per_texel + BACK_COEFF * order * order
    return texels * per_texel


def memory_budget():
    """Bytes a bake may take: half the machine's physical memory (8 GiB where unknown)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") // 2
    except (ValueError, OSError, AttributeError):
        return 8 << 30
