"""A bake's time and memory, estimated before it starts, and the refusal of one that would not fit.

The model counts what the bake will hold and trace from the meshes' sizes alone (no ray is traced
and nothing is evaluated, so the panel can show it on every redraw); its constants were fitted to
real bakes on a 2-core machine, and docs/bake.md ("Estimates") gives its error on other scenes.
"""

import os
from dataclasses import dataclass

import bpy
import numpy as np

from ...core.transfer import quadrature as transfer
from .. import caches
from ..scene import mesh_read
from .settings import SAMPLES_PER_TEXEL, BakeError, texel_memory

# Seconds per candidate ray (element x direction) on one thread: a base, and a part per SH
# coefficient that the quadrature accumulates (fitted on a quiet 2-core machine; docs/bake.md,
# "Estimates").
SECONDS_PER_RAY = 7.0e-8
SECONDS_PER_RAY_COEFF = 3.0e-10
SECONDS_FIXED = 0.03  # reading the scene, building the BVH, writing
SECONDS_PER_TEXEL = 4.0e-6  # rasterising a lightmap, its gutter, seams and image tiles (one thread)
BOUNCE_TIME = 1.0  # the bounces' extra time as a share of the direct bake's (measured 0.4 to 1.2)
COVERED_SHARE = 0.65  # the share of a lightmap's texels that its charts cover (time only)
ADAPTIVE_SHARE = 0.5  # the share of the covered texels adaptive sampling traces (measured 0.27 to 0.71)
# Bytes per element: positions, normals, indices and the stored attributes' fixed part; then per
# coefficient the float32 transfer, its local-frame copy and the colour attributes written.
BYTES_PER_ELEMENT = 120
BYTES_PER_COEFF = 11
WORK_BYTES = transfer.CHUNK_RAYS * transfer.RAY_BYTES  # the slices' ray buffers in flight
# Bounces: per node and coefficient the direct, running and total bounced transfer (three
# channels, float32), and per hit 4 + 4 x 3 bytes. A point keeps the hits of the half of the
# directions that ask for the nearest triangle and, of those, only the ones above its surface:
# at most about a quarter of its candidate rays (a closed room; an open scene far fewer).
BYTES_PER_NODE_COEFF = 4 * 3 * 3
BYTES_PER_HIT = 16
HIT_SHARE = 0.3
# A texel bake's bounced transfer goes the direct one's way to the image (gutter, seams, tiles),
# once per colour channel (at most 3).
TEXEL_BOUNCE_CHANNELS = 3
BYTES_PER_TRIANGLE = 120  # the occluder's copy and Embree's BVH
USABLE_SHARE = 0.9  # the share of the available memory a bake may take


@dataclass
class BakeEstimate:
    elements: int = 0  # points the bake computes (vertices; corners of flat-shaded meshes; texel samples)
    bounce_elements: int = 0  # points of other visible meshes that the bounces trace too
    rays: int = 0  # candidate rays: elements (texels for a texel bake) x directions; below-surface ones are skipped
    seconds: float = 0.0
    bytes: int = 0  # peak memory above the scene's (with bounces, at most: every ray hitting)
    available: int = 0  # the machine's available memory now (MemAvailable)
    threads: int = 1

    @property
    def fits(self):
        return self.bytes <= USABLE_SHARE * self.available

    def line(self):
        """'about 3 s, up to 250 MB (11 GB available)': what the panel shows before a bake."""
        return f"{_duration(self.seconds)}, up to {_size(self.bytes)} ({_size(self.available)} available)"

    def as_dict(self):
        return {
            "elements": self.elements,
            "bounce_elements": self.bounce_elements,
            "rays": self.rays,
            "seconds": self.seconds,
            "bytes": self.bytes,
            "available": self.available,
            "threads": self.threads,
            "fits": self.fits,
        }


def _duration(seconds):
    if seconds < 1.0:
        return "under 1 s"
    if seconds < 90.0:
        return f"about {seconds:.0f} s"
    return f"about {seconds / 60.0:.0f} min"


def _size(n):
    for limit, unit in ((2**30, "GB"), (2**20, "MB")):
        if n >= limit:
            return f"{n / limit:.1f} {unit}" if unit == "GB" else f"{n / limit:.0f} {unit}"
    return "under 1 MB"


def available_memory():
    """Bytes the machine can give now without swapping (Linux MemAvailable; elsewhere the free
    physical pages, else 8 GiB)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_AVPHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 8 << 30


_elements = {}  # (mesh pointer, sizes) -> points of a vertex bake with split normals
caches.on_clear(_elements.clear)  # mesh pointers mean nothing after a file load


def mesh_elements(mesh):
    """The points a vertex bake of `mesh` computes (mesh_read.bake_points): its vertices when
    each has one normal, else its distinct (vertex, normal) pairs, counted once per mesh size."""
    if mesh.normals_domain == "POINT":
        return len(mesh.vertices)
    key = (mesh.as_pointer(), len(mesh.vertices), len(mesh.loops), mesh.normals_domain)
    if key not in _elements:
        if len(_elements) > 64:
            _elements.clear()
        corners = mesh_read.read_corner_verts(mesh)
        pairs, _normals, _inverse = mesh_read.vertex_normal_pairs(
            corners, mesh_read.read_corner_normals(mesh), len(mesh.vertices)
        )
        _elements[key] = len(pairs)
    return _elements[key]


def mesh_is_open(mesh):
    """Whether `mesh` has a boundary edge (an edge of one face), so that a vertex bake also bakes
    its back side (core.transfer.back); counted once per mesh size."""
    key = ("open", mesh.as_pointer(), len(mesh.edges), len(mesh.loops))
    if key not in _elements:
        edges = np.empty(len(mesh.loops), dtype=np.int32)
        mesh.loops.foreach_get("edge_index", edges)
        _elements[key] = bool(np.any(np.bincount(edges, minlength=len(mesh.edges)) == 1))
    return _elements[key]


def _texel_elements(obj, settings):
    """Texel samples of a texel bake: resolution^2 (or area x density^2 over the packing) x S."""
    if settings.resolution:
        texels = settings.resolution**2
    else:
        areas = np.empty(len(obj.data.polygons), np.float32)
        obj.data.polygons.foreach_get("area", areas)
        scale = abs(float(np.linalg.det(np.array(obj.matrix_world)[:3, :3]))) ** (2.0 / 3.0)
        texels = float(areas.sum()) * scale * settings.texel_density**2
    return int(texels) * SAMPLES_PER_TEXEL


def estimate(objects, settings, scene=None, threads=None):
    """A BakeEstimate of baking `objects` (the selection: non-meshes count nothing) with
    `settings` (BakeSettings, validated here) in `scene` (default: the context's)."""
    settings.validate()
    scene = scene or bpy.context.scene
    threads = max(1, int(threads or settings.threads or scene.render.threads))
    meshes = [o for o in objects if isinstance(o, bpy.types.Object) and o.type == "MESH" and len(o.data.polygons)]
    texel = settings.target == "TEXELS"
    counts = [_texel_elements(o, settings) if texel else mesh_elements(o.data) for o in meshes]
    elements = int(sum(counts))
    # Open meshes trace their back side too: the same points (texel samples) again.
    back = sum(c for o, c in zip(meshes, counts) if mesh_is_open(o.data))
    order2 = settings.order**2
    triangles = 0
    bounce_elements = 0
    if settings.shadows:
        names = {o.name for o in meshes}
        for obj in scene.objects:
            if obj.type == "MESH" and obj.visible_get():
                triangles += len(obj.data.loops) - 2 * len(obj.data.polygons)  # (n - 2 per n-gon)
                if settings.bounces and obj.name not in names:
                    bounce_elements += mesh_elements(obj.data)
    # A texel's S samples share the direction set (each traces N / S of it): N rays per texel.
    texels = elements // SAMPLES_PER_TEXEL if texel else 0
    rays = (texels + back // SAMPLES_PER_TEXEL) * settings.samples if texel else (elements + back) * settings.samples
    all_rays = rays + bounce_elements * settings.samples
    traced = all_rays
    if texel:  # (covered texels only; adaptive sampling is off with bounces, but for the back sides)
        share = COVERED_SHARE * (ADAPTIVE_SHARE if settings.adaptive and not settings.bounces else 1.0)
        back_share = COVERED_SHARE * (ADAPTIVE_SHARE if settings.adaptive else 1.0)
        back_rays = back // SAMPLES_PER_TEXEL * settings.samples
        traced = share * (rays - back_rays) + back_share * back_rays + bounce_elements * settings.samples
    per_ray = SECONDS_PER_RAY + SECONDS_PER_RAY_COEFF * order2
    seconds = SECONDS_FIXED + (traced * per_ray + texels * SECONDS_PER_TEXEL) / threads
    nbytes = (elements + back) * (BYTES_PER_ELEMENT + BYTES_PER_COEFF * order2)
    if texel:
        nbytes = sum(
            texel_memory(
                settings.resolution or int(np.sqrt(c / SAMPLES_PER_TEXEL)), settings.order, back=mesh_is_open(o.data)
            )
            for o, c in zip(meshes, counts)
        )
    nbytes += triangles * BYTES_PER_TRIANGLE + WORK_BYTES
    if settings.bounces:
        seconds += BOUNCE_TIME * (seconds - SECONDS_FIXED)
        nodes = (texels or elements) + bounce_elements
        nbytes += nodes * order2 * BYTES_PER_NODE_COEFF + int(HIT_SHARE * all_rays) * BYTES_PER_HIT
        if texel:
            nbytes += TEXEL_BOUNCE_CHANNELS * sum(
                texel_memory(settings.resolution or int(np.sqrt(c / SAMPLES_PER_TEXEL)), settings.order, 0)
                for c in counts
            )
    return BakeEstimate(elements, bounce_elements, rays, float(seconds), int(nbytes), available_memory(), threads)


def refuse_past_memory(estimate_):
    """Raise BakeError, before anything is computed, when the estimate does not fit in the
    memory the machine has available."""
    if estimate_.fits:
        return
    raise BakeError(
        f"this bake would take about {_size(estimate_.bytes)} of memory and {_size(estimate_.available)} are "
        f"available: lower the order (memory grows with its square), bake fewer objects at once, "
        f"or use fewer bounces or directions"
    )
