"""The transfer bake in Blender: job, operator prt.bake_transfer, settings and sidebar panel.

BakeJob reads everything it needs from the depsgraph when it is created, computes chunk by chunk
(steps()) and writes all meshes at the end (finish()); nothing is written before that, so a
cancelled or failed bake leaves the meshes as they were (mesh_io.write_bakes also restores them
if the write itself fails). The maths is in prt_addon.core.transfer; docs/bake.md explains it.
"""

import json
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field

import bpy
import numpy as np

from ..core import raytrace, transfer
from ..core.directions import KINDS, make_directions
from . import mesh_io
from .panels import PRTSubPanel

BACKENDS = ("AUTO", "EMBREE", "BVHTREE")
MAX_ORDER = 16
# Ray origin offset along the normal: OFFSET_REL times the world bounding-box diagonal of the
# object being baked, and at least OFFSET_ULP times its largest coordinate (float32 rounding).
OFFSET_REL = 1e-4
OFFSET_ULP = 1e-5


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
    threads: int = 2

    def validate(self):
        if isinstance(self.order, bool) or not isinstance(self.order, (int, np.integer)) \
                or not 1 <= self.order <= MAX_ORDER:
            raise BakeError(f"order must be an integer from 1 to {MAX_ORDER}, got {self.order!r}")
        if isinstance(self.samples, bool) or not isinstance(self.samples, (int, np.integer)) \
                or self.samples < 2:
            raise BakeError(f"samples must be an integer >= 2, got {self.samples!r}")
        self.direction_set = str(self.direction_set).upper()
        if self.direction_set not in KINDS:
            raise BakeError(f"direction_set must be one of {KINDS}, got {self.direction_set!r}")
        self.backend = str(self.backend).upper()
        if self.backend not in BACKENDS:
            raise BakeError(f"backend must be one of {BACKENDS}, got {self.backend!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise BakeError(f"seed must be an integer >= 0, got {self.seed!r}")
        self.order, self.samples, self.seed = int(self.order), int(self.samples), int(self.seed)
        return self


@dataclass
class BakeReport:
    ok: bool = False
    cancelled: bool = False
    message: str = ""
    objects: list = field(default_factory=list)
    skipped: list = field(default_factory=list)  # [(name, reason)]
    backend: str = "NONE"
    seconds: float = 0.0
    rays_traced: int = 0
    rays_skipped: int = 0
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

    @property
    def rays_per_second(self):
        return self.rays_traced / self.seconds if self.seconds > 0 else 0.0

    def as_dict(self):
        d = asdict(self)
        d["skipped"] = [list(s) for s in self.skipped]
        return d

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
                f"Error estimate {self.error_estimate:.2e} "
                f"({100.0 * self.error_estimate_relative:.2f} % of |t|)",
            ]
        if self.note:
            lines.append(self.note)
        lines += [f"Skipped '{name}': {reason}" for name, reason in self.skipped]
        return lines


@dataclass
class _Plan:
    obj: object
    name: str
    mesh: object
    matrix: np.ndarray
    points: object  # mesh_io.BakePoints (None until prepared)
    fingerprint: str
    offset: float
    self_occludes: bool
    own_vertices: np.ndarray  # world-space float32 triangles of the evaluated object
    own_triangles: np.ndarray
    computation: object = None
    occluder: object = None
    boxes: object = None  # (K, 2, 3) boxes of the other occluders, or None (no culling)
    source: object = None  # (evaluated mesh, its local positions) until the points are read


class _LazyOccluder:
    """The real occluder, built on the first query or in the background after start() (the
    scene's Embree occluder: its build overlaps the job's set-up); queries wait for the build."""

    def __init__(self, backend, vertices, triangles):
        self.name = backend
        self.max_threads = 1 if backend == "BVHTREE" else raytrace.EmbreeOccluder.max_threads
        self._parts = (vertices, triangles)
        self._real = None
        self._lock = threading.Lock()
        self._started = None

    def start(self, pool):
        """Build in the background on `pool` (Embree only: the BVH build releases the GIL, and
        attaching the triangles as shared buffers takes microseconds where embreex's copying
        constructor would hold the GIL for its whole copy) while the caller prepares the rest.
        A failure there is not raised: the first query builds again and raises it, as without
        start()."""
        if self.name == "EMBREE" and self._started is None:
            self._started = pool.submit(self._build_quietly)

    def _build_quietly(self):
        try:
            self._build()
        except Exception:  # noqa: BLE001 - raised again by the first query
            pass

    @property
    def built(self):
        return self._real is not None

    def _build(self):
        with self._lock:
            if self._real is None:
                vertices, triangles = self._parts
                if self.name == "EMBREE":
                    self._real = raytrace.EmbreeOccluder(vertices, triangles)
                else:
                    from .bvh_backend import BVHTreeOccluder

                    self._real = BVHTreeOccluder(vertices, triangles)
                self._parts = None
        return self._real

    def occluded(self, origins, directions):
        real = self._real if self._real is not None else self._build()
        return real.occluded(origins, directions)


# Embree bake vs BVH tree bake throughput, measured by benchmarks/bench_bake.py (docs/bake.md).
FALLBACK_SLOWDOWN = "30 to 40"


def fallback_note():
    """The sentence shown when Auto falls back to the BVH tree because embreex does not import."""
    return (f"Embree (embreex) is not available on this system ({raytrace.EMBREE_IMPORT_ERROR}): "
            f"the slower BVH tree fallback was used (about {FALLBACK_SLOWDOWN} times slower, one thread)")


def resolve_backend(requested):
    requested = str(requested).upper()
    if requested == "AUTO":
        return "EMBREE" if raytrace.EMBREE_AVAILABLE else "BVHTREE"
    if requested == "EMBREE" and not raytrace.EMBREE_AVAILABLE:
        raise BakeError(
            f"the Embree backend is not available on this system ({raytrace.EMBREE_IMPORT_ERROR}): "
            "choose Auto or BVH Tree"
        )
    return requested


def _modifier_names(obj):
    return ", ".join(f"{m.name} ({m.type.replace('_', ' ').title()})" for m in obj.modifiers if m.show_viewport)


def _scene_parts(depsgraph, cache=None):
    """World-space triangles of every visible mesh instance: [(original object or None, V, T)].
    cache: {evaluated mesh pointer: (positions, triangles)} already read (filled in here)."""
    cache = {} if cache is None else cache
    parts = []
    for inst in depsgraph.object_instances:
        ob = inst.object
        if ob.type != "MESH":
            continue
        mesh = ob.data
        key = mesh.as_pointer()
        if key not in cache:
            positions = mesh_io.read_positions(mesh)
            cache[key] = (positions, mesh_io.read_triangles(mesh, positions))
        positions, triangles = cache[key]
        if len(triangles) == 0:
            continue
        owner = None if inst.is_instance else ob.original
        with np.errstate(invalid="ignore", over="ignore"):  # NaN/Inf vertices: dropped below
            world = mesh_io.transform_points(mesh_io.matrix_to_numpy(inst.matrix_world), positions)
            world = world.astype(np.float32)
        if not np.isfinite(world).all():  # NaN/Inf vertices cannot occlude: drop their triangles
            finite = np.isfinite(world).all(axis=1)
            world = np.where(finite[:, None], world, np.float32(0.0))
            triangles = triangles[finite[triangles].all(axis=1)]
            if len(triangles) == 0:
                continue
        parts.append((owner, world, triangles))
    return parts


def _concatenate(parts):
    if not parts:
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32)
    offsets = np.cumsum([0] + [len(v) for _o, v, _t in parts[:-1]])
    vertices = np.concatenate([v for _o, v, _t in parts])
    triangles = np.concatenate([t + np.int32(off) for (_o, _v, t), off in zip(parts, offsets)])
    return vertices, triangles


class BakeJob:
    """One bake of several objects: create, then run() or iterate steps() and call finish()."""

    def __init__(self, objects, settings=None, depsgraph=None):
        self.settings = (settings or BakeSettings()).validate()
        self.started = time.perf_counter()
        self.report = BakeReport(
            order=self.settings.order, samples=self.settings.samples,
            direction_set=self.settings.direction_set,
        )
        self._cancel = False
        objects = list(objects or [])
        if not objects:
            raise BakeError("nothing selected: select the mesh objects to bake")
        if depsgraph is None:
            depsgraph = bpy.context.evaluated_depsgraph_get()
        self.backend = resolve_backend(self.settings.backend)
        self.plans = []
        self._reads = {}  # evaluated mesh pointer -> (positions, triangles), read once
        self._pool = ThreadPoolExecutor(max(1, self.settings.threads), thread_name_prefix="prt-bake")
        try:
            self._read_scene(depsgraph)
            seen_meshes = {}
            for obj in objects:
                reason = self._check(obj, depsgraph, seen_meshes)
                if isinstance(reason, str):
                    self.report.skipped.append((getattr(obj, "name", repr(obj)), reason))
                else:
                    self.plans.append(reason)
            if not self.plans:
                reasons = "; ".join(f"'{n}' {r}" for n, r in self.report.skipped)
                raise BakeError(f"nothing to bake: {reasons}")
            self._assign_occluders()
            # The scene's BVH builds on a worker while the baked points are prepared here
            # (docs/bake.md, "Throughput"); not at all when no object can trace a ray.
            scene = self._occluder
            if scene is not None and any(self._may_trace(p) for p in self.plans if p.occluder is scene):
                scene.start(self._pool)
            self.directions = make_directions(self.settings.direction_set, self.settings.samples,
                                              self.settings.seed)
            # The first object's slices start as soon as its points are ready: they trace while
            # the other objects' points are read.
            for index, plan in enumerate(self.plans):
                mesh_eval, positions = plan.source
                plan.points = mesh_io.bake_points(mesh_eval, plan.matrix, positions)
                plan.source = None
                plan.computation = self._computation(plan)
                if index == 0:
                    plan.computation.start()
            self._parts = self._reads = None  # not needed any more: free the arrays
        except BaseException:
            self.close()
            raise
        self.total_points = sum(len(p.points.positions) for p in self.plans)

    def _check(self, obj, depsgraph, seen_meshes):
        if not isinstance(obj, bpy.types.Object):
            return f"is not an object ({type(obj).__name__})"
        name = obj.name
        if obj.type != "MESH":
            return (f"is a {obj.type.lower()}, not a mesh: convert it (Object > Convert > Mesh) "
                    "to bake it")
        mesh = obj.data
        if obj.mode == "EDIT" or mesh.is_editmode:
            return "is in Edit Mode: switch to Object Mode, then bake"
        if obj.library is not None or mesh.library is not None:
            return ("is linked from a library and cannot be written: make it local "
                    "(Object > Relations > Make Local > Selected Objects and Data) to bake it")
        if len(mesh.polygons) == 0:
            return "has no faces: a transfer bake needs faces (it only has vertices/edges)"
        if mesh.name in seen_meshes:
            return (f"shares its mesh '{mesh.name}' with '{seen_meshes[mesh.name]}': make it single "
                    "user (Object > Relations > Make Single User > Object & Data) to bake both")
        obj_eval = obj.evaluated_get(depsgraph)
        mesh_eval = obj_eval.data
        fingerprint = mesh_io.topology_fingerprint(mesh)
        modified = any(m.show_viewport for m in obj.modifiers)
        if modified and mesh_io.topology_fingerprint(mesh_eval) != fingerprint:
            return (f"has modifiers that change its topology [{_modifier_names(obj)}]: apply them "
                    "(Object > Apply > Visual Geometry to Mesh) or turn them off in the viewport, "
                    "then bake again")
        matrix = mesh_io.matrix_to_numpy(obj_eval.matrix_world)
        if not np.isfinite(matrix).all():
            return "has a non-finite transform (NaN or infinity in location, rotation or scale)"
        cached = self._reads.get(mesh_eval.as_pointer())
        positions = cached[0] if cached else mesh_io.read_positions(mesh_eval)
        if not np.isfinite(positions).all():
            bad = int(np.count_nonzero(~np.isfinite(positions).all(axis=1)))
            return (f"has {bad} vertices with non-finite coordinates (NaN or infinity): fix or delete "
                    "them (e.g. in Edit Mode, Mesh > Clean Up), then bake again")
        world = mesh_io.transform_points(matrix, positions)
        lower, upper = raytrace.bounding_box(world)
        diagonal = float(np.linalg.norm(upper - lower))
        if not diagonal > 0.0 or abs(np.linalg.det(matrix[:3, :3])) < 1e-30:
            return ("has zero size (all its vertices are at one point, or a scale of 0): "
                    "its faces have no area to bake")
        seen_meshes[mesh.name] = name
        triangles = cached[1] if cached else mesh_io.read_triangles(mesh_eval, positions)
        offset = max(OFFSET_REL * diagonal, OFFSET_ULP * float(np.abs(world).max()), 1e-30)
        self_occludes = True
        if self.settings.cull and not mesh_eval.has_custom_normals:
            self_occludes = not raytrace.cannot_self_occlude(world, triangles)
        return _Plan(obj, name, mesh, matrix, None, fingerprint, offset, self_occludes,
                     world.astype(np.float32), triangles, source=(mesh_eval, positions))

    def _read_scene(self, depsgraph):
        """Read the scene's triangles into their (not yet built) occluder (shadows from the scene)."""
        s = self.settings
        self._parts, self._occluder = [], None
        if s.shadows and not s.self_shadow_only:
            self._parts = _scene_parts(depsgraph, self._reads)
            vertices, triangles = _concatenate(self._parts)
            if len(triangles):
                self._occluder = _LazyOccluder(self.backend, vertices, triangles)

    @staticmethod
    def _may_trace(plan):
        """Whether any ray of the plan can be traced (else culling skips them all): its own mesh
        can occlude it, other occluders exist, or culling is off."""
        return plan.boxes is None or len(plan.boxes) > 0 or bool(plan.self_occludes)

    def _assign_occluders(self):
        s = self.settings
        scene_occluder, parts = self._occluder, self._parts
        for plan in self.plans:
            occluder, boxes = None, None
            if s.shadows:
                if s.self_shadow_only:
                    occluder = _LazyOccluder(self.backend, plan.own_vertices, plan.own_triangles)
                    boxes = np.zeros((0, 2, 3))
                else:
                    occluder = scene_occluder
                    others = [v for owner, v, _t in parts if owner is None or owner != plan.obj]
                    boxes = np.array([raytrace.bounding_box(v) for v in others]).reshape(-1, 2, 3)
                    if not any(owner == plan.obj for owner, _v, _t in parts):
                        plan.self_occludes = False  # hidden from the scene: not an occluder
            if not s.cull:
                boxes = None
            plan.occluder, plan.boxes = occluder, boxes

    def _computation(self, plan):
        s = self.settings
        return transfer.TransferComputation(
            plan.points.positions, plan.points.normals, self.directions, s.order,
            occluder=plan.occluder, offset=plan.offset, self_occludes=plan.self_occludes,
            other_boxes=plan.boxes, chunk_rays=s.chunk_rays, threads=s.threads, pool=self._pool,
        )

    def close(self):
        """Stop the work queued for this job and its threads (idempotent). steps() does it when
        it ends; the operator calls it too, since a generator closed before its first step never
        runs its own clean-up."""
        for plan in self.plans:
            if plan.computation is not None:
                plan.computation.close()
        self._pool.shutdown(wait=True, cancel_futures=True)

    def cancel(self):
        self._cancel = True

    @property
    def fraction(self):
        done = sum(p.computation.done for p in self.plans)
        return done / self.total_points if self.total_points else 1.0

    def steps(self):
        """Generator: one chunk per step, yielding (fraction done, status text)."""
        try:
            for index, plan in enumerate(self.plans):
                comp = plan.computation
                while True:
                    if self._cancel:
                        raise transfer.Cancelled()
                    more = comp.step()
                    yield self.fraction, (
                        f"Baking '{plan.name}' ({index + 1}/{len(self.plans)}): "
                        f"{100.0 * self.fraction:.0f} %"
                    )
                    if not more:
                        break
                comp.close()
        finally:
            self.close()

    def finish(self):
        """Write every baked mesh (all or nothing) and return the report."""
        s, rep = self.settings, self.report
        if self._cancel:
            raise transfer.Cancelled()
        items, errors, square_norm_sum = [], [], 0.0
        stats_all = transfer.TransferStats()
        backends = set()
        for plan in self.plans:
            try:
                current = mesh_io.topology_fingerprint(plan.mesh)
            except ReferenceError:
                raise BakeError(f"'{plan.name}' was deleted during the bake") from None
            if current != plan.fingerprint:
                raise BakeError(f"the topology of '{plan.name}' changed during the bake: bake again")
            comp = plan.computation
            stats = comp.stats
            stats_all.add(stats)
            traced = plan.occluder is not None and getattr(plan.occluder, "built", False)
            backend = self.backend if traced and stats.rays_traced else "NONE"
            if backend != "NONE":
                backends.add(backend)
            local = transfer.to_local_frame(comp.coeffs, plan.matrix[:3, :3])
            values = local if plan.points.scatter is None else local[plan.points.scatter]
            result = comp.result()
            errors.append(result.error.astype(np.float64))
            square_norm_sum += result.square_norm_sum()
            record = {
                "version": mesh_io.FORMAT_VERSION,
                "order": s.order,
                "samples": s.samples,
                "direction_set": s.direction_set,
                "seed": int(s.seed),
                "shadows": bool(s.shadows),
                "self_shadow_only": bool(s.self_shadow_only),
                "backend": backend,
                "fingerprint": plan.fingerprint,
                "offset": float(plan.offset),
                "seconds": float(stats.seconds),
                "rays_traced": int(stats.rays_traced),
                "rays_skipped": int(stats.rays_skipped),
                "error_estimate": result.error_rms(),
                "error_estimate_relative": result.error_relative(),
            }
            items.append((plan.mesh, values, plan.points.domain, record))
        mesh_io.write_bakes(items)
        err = np.concatenate(errors)
        rep.ok = True
        rep.objects = [p.name for p in self.plans]
        rep.backend = backends.pop() if backends else "NONE"
        if rep.backend == "BVHTREE" and s.backend == "AUTO":
            rep.note = fallback_note()
        rep.seconds = time.perf_counter() - self.started
        rep.rays_traced = stats_all.rays_traced
        rep.rays_skipped = stats_all.rays_skipped
        rep.skipped_below_horizon = stats_all.skipped_below_horizon
        rep.skipped_unoccludable = stats_all.skipped_unoccludable
        rep.skipped_shadows_off = stats_all.skipped_shadows_off
        rep.points = int(len(err))
        rep.error_estimate = float(np.sqrt(np.mean(err**2))) if len(err) else 0.0
        rms_norm = float(np.sqrt(square_norm_sum / len(err))) if len(err) else 0.0
        rep.error_estimate_relative = rep.error_estimate / rms_norm if rms_norm > 0 else 0.0
        rep.message = rep.summary_lines()[0]
        return rep

    def run(self, progress=None):
        """Compute and write; progress(fraction, text) after each chunk (an exception aborts)."""
        for fraction, text in self.steps():
            if progress is not None:
                progress(fraction, text)
        return self.finish()


def bake(objects, order=4, samples=256, shadows=True, backend="AUTO", direction_set="FIBONACCI",
         seed=0, self_shadow_only=False, progress=None, cull=True, depsgraph=None,
         chunk_rays=transfer.CHUNK_RAYS, threads=2):
    """Bake and write; returns a BakeReport. Raises BakeError when nothing can be baked."""
    if objects is not None and isinstance(objects, bpy.types.Object):
        objects = [objects]
    settings = BakeSettings(order, samples, direction_set, seed, shadows, self_shadow_only,
                            backend, cull, chunk_rays, threads)
    job = BakeJob(objects, settings, depsgraph)
    return job.run(progress)


def status(obj, use_cache=False):
    """('fresh' | 'stale' | 'none', reason) for an object."""
    if obj is None or getattr(obj, "type", None) != "MESH":
        return "none", "not a mesh object"
    state, reason = mesh_io.bake_status(obj.data, use_cache=use_cache)
    return state.lower(), reason


# --- UI ------------------------------------------------------------------------------------


class PRT_PG_bake_settings(bpy.types.PropertyGroup):
    order: bpy.props.IntProperty(
        name="Order", description="SH order n: n*n transfer coefficients per vertex",
        default=4, min=1, max=MAX_ORDER,
    )
    samples: bpy.props.IntProperty(
        name="Samples", description="Directions of the shared direction set (rays per vertex)",
        default=256, min=16, max=65536,
    )
    direction_set: bpy.props.EnumProperty(
        name="Directions",
        items=[
            ("FIBONACCI", "Fibonacci", "Spherical Fibonacci set, randomly rotated (most accurate)"),
            ("STRATIFIED", "Stratified", "Jittered equal-area strata"),
            ("UNIFORM", "Uniform", "Independent uniform random directions"),
        ],
        default="FIBONACCI",
    )
    seed: bpy.props.IntProperty(name="Seed", description="Seed of the direction set", default=0, min=0)
    shadows: bpy.props.BoolProperty(
        name="Shadows", description="Trace visibility (shadowed transfer); off: cosine only",
        default=True,
    )
    self_shadow_only: bpy.props.BoolProperty(
        name="Self-Shadow Only", description="Only the object itself occludes (no other objects)",
        default=False,
    )
    backend: bpy.props.EnumProperty(
        name="Backend",
        items=[
            ("AUTO", "Auto", "Embree when available, else Blender's BVH tree"),
            ("EMBREE", "Embree", "embreex (Embree 4), multi-threaded"),
            ("BVHTREE", "BVH Tree", "mathutils.bvhtree, single-threaded and slower"),
        ],
        default="AUTO",
    )
    last_report: bpy.props.StringProperty(name="Last Report", default="", options={"SKIP_SAVE"})


def settings_from(group):
    """BakeSettings of a PRT_PG_bake_settings. (A module function: a method on the property
    group made bpy 4.2 crash at exit after register/unregister.)"""
    return BakeSettings(group.order, group.samples, group.direction_set, group.seed, group.shadows,
                        group.self_shadow_only, group.backend)


# Reports of bakes that changed nothing (refused, failed, cancelled) are kept in memory only, so
# that a refused bake leaves the .blend exactly as it was; a finished bake saves its report in
# scene.prt_bake.last_report (it changed the file anyway).
_unsaved_reports = {}  # scene.session_uid -> report dict


def _scene_key(scene):
    return getattr(scene, "session_uid", None) or scene.as_pointer()


def _store_report(scene, report):
    if not report.ok:
        _unsaved_reports[_scene_key(scene)] = report.as_dict()
        return
    _unsaved_reports.pop(_scene_key(scene), None)
    settings = getattr(scene, "prt_bake", None)
    if settings is not None:
        settings.last_report = json.dumps(report.as_dict())


def last_report(scene):
    """The report (a dict, see BakeReport.as_dict) of the last bake in this scene, or None: that
    of a bake that changed nothing this session if there is one, else the saved one."""
    data = _unsaved_reports.get(_scene_key(scene))
    if data is not None:
        return dict(data)
    saved = getattr(getattr(scene, "prt_bake", None), "last_report", "")
    if not saved:
        return None
    try:
        return json.loads(saved)
    except ValueError:
        return None


def _report_to_operator(op, report):
    if report.ok:
        op.report({"INFO"}, "PRT: " + " | ".join(report.summary_lines()[:1] + report.summary_lines()[4:5]))
    if report.note:
        op.report({"WARNING"}, f"PRT: {report.note}")
    for name, reason in report.skipped:
        op.report({"WARNING"}, f"PRT: skipped '{name}': {reason}")


TIME_SLICE = 0.1  # seconds of work per timer event of the modal bake
# Timer events closer than this to the end of the previous slice do no work: an Event does not
# say which timer fired, so other add-ons' timers would otherwise add slices and stall the UI.
TIMER_GAP = 0.015
_running = set()  # operators with a live timer, removed in unregister_extra()
_NAVIGATION = {
    "MIDDLEMOUSE", "WHEELUPMOUSE", "WHEELDOWNMOUSE", "MOUSEMOVE", "INBETWEEN_MOUSEMOVE",
    "TRACKPADPAN", "TRACKPADZOOM", "MOUSEROTATE", "NDOF_MOTION",
}


class PRT_OT_bake_transfer(bpy.types.Operator):
    """Bake shadowed SH transfer into the selected mesh objects"""

    bl_idname = "prt.bake_transfer"
    bl_label = "Bake"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        if context.mode != "OBJECT":
            cls.poll_message_set("Switch to Object Mode to bake")
            return False
        return True

    def _job(self, context):
        settings = settings_from(context.scene.prt_bake)
        try:
            if _running:
                raise BakeError("a bake is already running: wait for it to finish, or press Esc "
                                "to cancel it, then bake again")
            return BakeJob(context.selected_objects, settings, context.evaluated_depsgraph_get())
        except BakeError as exc:
            failed = BakeReport(message=f"Bake not started: {exc}")
            _store_report(context.scene, failed)
            self.report({"ERROR"}, f"PRT: {exc}")
            return None

    def execute(self, context):
        job = self._job(context)
        if job is None:
            return {"CANCELLED"}
        try:
            report = job.run()
        except Exception as exc:  # noqa: BLE001 - any failure must leave the meshes untouched
            _store_report(context.scene, BakeReport(message=f"Bake failed: {exc}"))
            self.report({"ERROR"}, f"PRT: bake failed, nothing was changed: {exc}")
            return {"CANCELLED"}
        _store_report(context.scene, report)
        _report_to_operator(self, report)
        return {"FINISHED"}

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        job = self._job(context)
        if job is None:
            return {"CANCELLED"}
        self._bake = job
        try:
            self._steps = job.steps()
            wm = context.window_manager
            self._timer = wm.event_timer_add(0.02, window=context.window)
            wm.progress_begin(0, 100)
            wm.modal_handler_add(self)
            _running.add(self)
        except BaseException:
            # The job's first slices are already running: stop them (nothing was written).
            try:
                self._cleanup(context)
            finally:
                job.close()
            raise
        return {"RUNNING_MODAL"}

    def _cleanup(self, context):
        wm = context.window_manager
        if getattr(self, "_timer", None) is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        if getattr(self, "_steps", None) is not None:
            self._steps.close()
        if getattr(self, "_bake", None) is not None:
            self._bake.close()
        _running.discard(self)
        for area in context.screen.areas if context.screen else ():
            area.tag_redraw()

    def modal(self, context, event):
        if event.type == "ESC":
            self._bake.cancel()
            self._cleanup(context)
            _store_report(context.scene, BakeReport(cancelled=True, message="Bake cancelled: nothing was changed"))
            self.report({"WARNING"}, "PRT: bake cancelled, nothing was changed")
            return {"CANCELLED"}
        if self._bake._cancel:  # cancelled from outside (the add-on was disabled): write nothing
            self._cleanup(context)
            self.report({"WARNING"}, "PRT: bake cancelled, nothing was changed")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"} if event.type in _NAVIGATION else {"RUNNING_MODAL"}
        if time.perf_counter() - getattr(self, "_slice_end", float("-inf")) < TIMER_GAP:
            return {"RUNNING_MODAL"}  # (another timer right after our slice: let the UI run)
        deadline = time.perf_counter() + TIME_SLICE
        try:
            while True:  # at least one chunk per timer event
                fraction, text = next(self._steps)
                if time.perf_counter() >= deadline:
                    break
        except StopIteration:
            try:
                report = self._bake.finish()
            except Exception as exc:  # noqa: BLE001
                return self._fail(context, exc)
            self._cleanup(context)
            _store_report(context.scene, report)
            _report_to_operator(self, report)
            return {"FINISHED"}
        except Exception as exc:  # noqa: BLE001
            return self._fail(context, exc)
        context.window_manager.progress_update(100.0 * fraction)
        if context.workspace is not None:
            context.workspace.status_text_set(f"PRT: {text} (Esc to cancel)")
        self._slice_end = time.perf_counter()
        return {"RUNNING_MODAL"}

    def _fail(self, context, exc):
        self._cleanup(context)
        _store_report(context.scene, BakeReport(message=f"Bake failed: {exc}"))
        self.report({"ERROR"}, f"PRT: bake failed, nothing was changed: {exc}")
        return {"CANCELLED"}


class VIEW3D_PT_prt_bake(PRTSubPanel, bpy.types.Panel):
    bl_idname = "VIEW3D_PT_prt_bake"
    bl_label = "Bake Transfer"

    def draw(self, context):
        layout = self.layout
        settings = context.scene.prt_bake
        col = layout.column(align=True)
        col.prop(settings, "order")
        col.prop(settings, "samples")
        col.prop(settings, "direction_set")
        col.prop(settings, "shadows")
        sub = col.column(align=True)
        sub.enabled = settings.shadows
        sub.prop(settings, "self_shadow_only")
        sub.prop(settings, "backend")
        if not raytrace.EMBREE_AVAILABLE:
            if settings.backend == "EMBREE":
                layout.label(text="Embree is not available here: choose Auto or BVH Tree", icon="ERROR")
            else:
                col = layout.column(align=True)
                col.label(text="Embree (embreex) is not available here:", icon="INFO")
                col.label(text=f"the BVH tree fallback bakes {FALLBACK_SLOWDOWN}x slower")
        layout.operator(PRT_OT_bake_transfer.bl_idname, text="Bake", icon="RENDER_STILL")
        stale = []
        for obj in context.selected_objects[:16]:
            if obj.type == "MESH":
                state, reason = status(obj, use_cache=True)
                if state == "stale":
                    stale.append((obj.name, reason))
        obj = context.active_object
        if obj is not None and obj.type == "MESH":
            state, reason = status(obj, use_cache=True)
            icon = {"fresh": "CHECKMARK", "stale": "ERROR", "none": "DOT"}[state]
            layout.label(text=f"{obj.name}: {state} ({reason})", icon=icon)
        for name, reason in stale:
            if obj is None or name != obj.name:
                layout.label(text=f"{name}: stale ({reason})", icon="ERROR")
        data = last_report(context.scene)
        if data:
            try:
                report = BakeReport(**{k: v for k, v in data.items() if k in BakeReport.__dataclass_fields__})
            except (ValueError, TypeError):
                return
            box = layout.box()
            for line in report.summary_lines():
                box.label(text=line)


CLASSES = [PRT_PG_bake_settings, PRT_OT_bake_transfer, VIEW3D_PT_prt_bake]


def register_extra():
    bpy.types.Scene.prt_bake = bpy.props.PointerProperty(type=PRT_PG_bake_settings)


def unregister_extra():
    """Stop a running modal bake (the add-on is being disabled): cancel it, remove its timer,
    end the progress bar and status text, close the worker threads. Nothing is written."""
    for op in list(_running):
        _running.discard(op)
        for step in ("cancel", "timer", "steps", "close", "progress"):
            try:
                if step == "cancel":
                    op._bake.cancel()
                elif step == "timer" and op._timer is not None:
                    bpy.context.window_manager.event_timer_remove(op._timer)
                    op._timer = None
                elif step == "steps":
                    op._steps.close()
                elif step == "close":
                    op._bake.close()
                elif step == "progress":
                    wm = bpy.context.window_manager
                    if wm is not None:
                        wm.progress_end()
                    workspace = bpy.context.workspace
                    if workspace is not None:
                        workspace.status_text_set(None)
            except (ReferenceError, AttributeError, RuntimeError, TypeError, ValueError):
                pass
    if hasattr(bpy.types.Scene, "prt_bake"):
        del bpy.types.Scene.prt_bake
