"""The bake job: reads the scene, computes transfer slice by slice, writes all meshes at the end.

BakeJob reads everything it needs from the depsgraph when it is created, computes chunk by chunk
(steps()) and writes all meshes at the end (finish()); nothing is written before that, so a
cancelled or failed bake leaves the meshes as they were (storage.write_bakes also restores them
if the write itself fails). The maths is in prt_addon.core.transfer.quadrature; docs/bake.md explains it.
"""

import time
from concurrent.futures import ThreadPoolExecutor

import bpy
import numpy as np

from ...core.sh import frames
from ...core.sh.directions import make_directions
from ...core.trace import raytrace
from ...core.trace.occluders import LazyOccluder
from ...core.transfer import adaptive, bounce_hits, quadrature as transfer
from ...core.transfer.mesh import concatenate_parts
from ..scene import mesh_read, storage
from ..scene.occluders import BUILDERS
from ..scene.parts import scene_parts
from .bounces import BounceSystem
from .estimate import estimate, refuse_past_memory
from .plans import NO_GEOMETRY, back_computation, back_values, bake_record, check_object
from .settings import BakeError, BakeReport, BakeSettings, blender_threads, fallback_note, resolve_backend
from .texels import bakes_texels, prepare_texels, texel_computation, texel_image, unwrap_ahead, within_memory

# Progress weight of one bounce pass per node, against one traced point (measured ~0.1 to 0.3).
PASS_WORK = 0.2


class BakeJob:
    """One bake of several objects: create, then run() or iterate steps() and call finish()."""

    def __init__(self, objects, settings=None, depsgraph=None):
        self.settings = (settings or BakeSettings()).validate()
        self.started = time.perf_counter()
        self.report = BakeReport(
            order=self.settings.order,
            samples=self.settings.samples,
            direction_set=self.settings.direction_set,
            target=self.settings.target,
        )
        self._cancel = False
        objects = list(objects or [])
        if not objects:
            raise BakeError("nothing selected: select the mesh objects to bake")
        if depsgraph is None:
            depsgraph = bpy.context.evaluated_depsgraph_get()
        self.backend = resolve_backend(self.settings.backend)
        if self.settings.threads is None:
            self.settings.threads = blender_threads(depsgraph.scene)
        self.plans = []
        self.bounce = None  # BounceSystem of an interreflected bake
        self._sink = bounce_hits.LateSink() if self.settings.bounces else None  # its computations' hit sink
        self._sources = [] if self.settings.bounces else None
        self._reads = {}  # evaluated mesh pointer -> (positions, triangles), read once
        self._texel_bytes = 0  # the texel bakes' estimated peak memory so far
        self._pool = ThreadPoolExecutor(max(1, self.settings.threads), thread_name_prefix="prt-bake")
        try:
            self._unwrapped = unwrap_ahead(objects, self.settings)
            self._read_scene(depsgraph)
            seen_meshes = {}
            for obj in objects:
                reason = check_object(obj, depsgraph, seen_meshes, self._reads, self.settings.cull)
                if isinstance(reason, str):
                    name = getattr(obj, "name", repr(obj))
                    quiet = getattr(obj, "type", None) in NO_GEOMETRY
                    (self.report.left_out if quiet else self.report.skipped).append((name, reason))
                else:
                    self.plans.append(reason)
            if not self.plans:
                reasons = "; ".join(f"'{n}' {r}" for n, r in self.report.skipped + self.report.left_out)
                raise BakeError(f"nothing to bake: {reasons}")
            self.estimate = estimate([p.obj for p in self.plans], self.settings, depsgraph.scene)
            refuse_past_memory(self.estimate)  # (before any ray: nothing has been allocated for it)
            self._assign_occluders()
            # The scene's BVH builds on a worker while the baked points are prepared here
            # (docs/bake.md, "Throughput"); not at all when no object can trace a ray.
            scene = self._occluder
            if scene is not None and any(self._may_trace(p) for p in self.plans if p.occluder is scene):
                scene.start(self._pool)
            self.directions = make_directions(self.settings.direction_set, self.settings.samples, self.settings.seed)
            # The first object's slices start as soon as its points are ready: they trace while
            # the other objects' points are read and, in an interreflected bake, while the bounce
            # system reads its tables (which need every part's nodes): hits that come before
            # those are kept as they came until the slice is collected (core.transfer.bounce_hits.LateSink).
            for index, plan in enumerate(self.plans):
                mesh_eval, positions = plan.source
                if bakes_texels(plan, self.settings):
                    self._texel_plan(plan, mesh_eval, positions)
                else:
                    plan.points = mesh_read.bake_points(mesh_eval, plan.matrix, positions)
                plan.source = None
                plan.computation = self._computation(plan)
                plan.back = back_computation(self, plan)
                if index == 0:
                    plan.computation.start()
            if self.settings.bounces:
                self.bounce = BounceSystem(self, self._parts, self._sources)
                self._sink.set(self.bounce.sink)
            self._parts = self._reads = self._sources = None  # not needed any more: free the arrays
        except BaseException:
            self.close()
            raise
        self.total_points = sum(c.total for p in self.plans for c in p.computations())
        self.bounce_points = self.bounce.extra_points if self.bounce else 0
        self._pass_work = PASS_WORK * self.bounce.n_nodes * self.settings.bounces if self.bounce else 0.0

    def _read_scene(self, depsgraph):
        """Read the scene's triangles into their (not yet built) occluder (shadows from the scene)."""
        s = self.settings
        self._parts, self._occluder = [], None
        if s.shadows and not s.self_shadow_only:
            self._parts = scene_parts(depsgraph, self._reads, self._sources)
            vertices, triangles = concatenate_parts(self._parts)
            if len(triangles):
                self._occluder = LazyOccluder(self.backend, vertices, triangles, BUILDERS)

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
                    occluder = LazyOccluder(self.backend, plan.own_vertices, plan.own_triangles, BUILDERS)
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

    def _texel_plan(self, plan, mesh_eval, positions):
        s = self.settings
        shadowed_by_scene = plan.occluder is not None and plan.occluder is self._occluder
        others = [(o, v, t) for o, v, t in self._parts if o is None or o != plan.obj] if shadowed_by_scene else []
        plan.texels = prepare_texels(plan, mesh_eval, positions, s, others, BUILDERS[self.backend], self._unwrapped)
        back = plan.texels.back_normals is not None
        self._texel_bytes = within_memory(self._texel_bytes, plan.texels.resolution, s.order, back)
        self.report.texel_notes += [f"'{plan.name}': {note}" for note in plan.texels.notes]

    def _computation(self, plan):
        if plan.texels is not None:
            return texel_computation(plan, self.directions, self.settings, self._pool, hit_sink=self._sink)
        # The point's own surface moves each origin into its own faces as well as along the
        # normal, so that rays from a point in another surface's plane (a box standing on the
        # ground) do not slip under it (docs/bake.md, "Contacts"). Unshadowed: not needed.
        surface = None if plan.occluder is None else (plan.own_vertices, plan.own_triangles)
        return self.transfer_computation(
            plan.points, plan.occluder, plan.offset, plan.self_occludes, plan.boxes, surface, self._sink
        )

    def transfer_computation(self, points, occluder, offset, self_occludes, boxes, surface, hit_sink=None):
        """A TransferComputation of `points` (BakePoints) with this job's directions, settings
        and threads (the bake's objects, and the bounce system's other meshes)."""
        s = self.settings
        return transfer.TransferComputation(
            points.positions,
            points.normals,
            self.directions,
            s.order,
            occluder=occluder,
            offset=offset,
            self_occludes=self_occludes,
            other_boxes=boxes,
            chunk_rays=s.chunk_rays,
            threads=s.threads,
            pool=self._pool,
            surface=surface,
            point_vertex=points.vertex,
            hit_sink=hit_sink,
        )

    def close(self):
        """Stop the work queued for this job and its threads (idempotent). steps() does it when
        it ends; the operator calls it too, since a generator closed before its first step never
        runs its own clean-up."""
        for comp in (c for plan in self.plans for c in plan.computations()):
            comp.close()
        if self.bounce is not None:
            self.bounce.close()
        self._pool.shutdown(wait=True, cancel_futures=True)

    def cancel(self):
        self._cancel = True

    @property
    def fraction(self):
        done = sum(c.done for p in self.plans for c in p.computations())
        total = self.total_points + self.bounce_points + self._pass_work
        if self.bounce is not None:
            done += sum(c.done for _f, c in self.bounce.node_computations)
            if self.bounce.passes is not None:
                done += self._pass_work * self.bounce.passes.done / self.settings.bounces
        return done / total if total else 1.0

    def _computations(self):
        """(label, computation) in the order steps() runs them."""
        named = [(f"Baking '{p.name}' ({i + 1}/{len(self.plans)})", p.computation) for i, p in enumerate(self.plans)]
        named += [(f"Baking the back of '{p.name}'", p.back) for p in self.plans if p.back is not None]
        if self.bounce is not None:
            named += [("Tracing the other meshes for the bounces", c) for _f, c in self.bounce.node_computations]
        return named

    def steps(self):
        """Generator: one chunk per step, yielding (fraction done, status text)."""
        try:
            named = self._computations()
            for index, (label, comp) in enumerate(named):
                following = self.plans[index + 1].computation if index + 1 < len(self.plans) else None
                while True:
                    if self._cancel:
                        raise transfer.Cancelled()
                    more = comp.step()
                    if more and following is not None and comp.fully_queued:
                        following.start()  # (its slices queue behind the last ones: no thread waits)
                    yield (done := self.fraction), f"{label}: {100.0 * done:.0f} %"  # (one sum a step)
                    if not more:
                        break
                comp.close()
                if index < len(self.plans):
                    self._texel_image_early(self.plans[index])
            if self.bounce is not None:
                started = time.perf_counter()
                self.bounce.start_passes(self.plans)
                while True:
                    if self._cancel:
                        raise transfer.Cancelled()
                    more = self.bounce.step_pass()
                    done = self.bounce.passes.done
                    yield self.fraction, f"Bouncing light: pass {done}/{self.settings.bounces}"
                    if not more:
                        break
                self.report.bounce_seconds = time.perf_counter() - started
        finally:
            self.close()

    def _texel_image_early(self, plan):
        """A texel bake's image as its tracing ends, while the next slices trace (not with bounces)."""
        if plan.texels is not None and self.bounce is None:
            local = frames.to_local_frame(plan.computation.coeffs, plan.matrix[:3, :3])
            plan.image = texel_image(plan.texels.samples, local, plan.texels.seams)

    def finish(self):
        """Write every baked mesh (all or nothing) and return the report."""
        s, rep = self.settings, self.report
        if self._cancel:
            raise transfer.Cancelled()
        items, errors, square_norm_sum = [], [], 0.0
        stats_all, front = transfer.TransferStats(), transfer.TransferStats()
        backends = set()
        for plan in self.plans:
            try:
                current = mesh_read.topology_fingerprint(plan.mesh)
            except ReferenceError:
                raise BakeError(f"'{plan.name}' was deleted during the bake") from None
            if current != plan.fingerprint:
                raise BakeError(f"the topology of '{plan.name}' changed during the bake: bake again")
            comp = plan.computation
            stats = comp.stats
            stats_all.add(stats)
            front.add(stats)
            if plan.back is not None:
                stats_all.add(plan.back.stats)
            traced = plan.occluder is not None and getattr(plan.occluder, "built", False)
            backend = self.backend if traced and stats.rays_traced else "NONE"
            if backend != "NONE":
                backends.add(backend)
            if plan.image is not None:
                values = plan.image
            else:
                local = frames.to_local_frame(comp.coeffs, plan.matrix[:3, :3])
                if plan.texels is not None:
                    values = texel_image(plan.texels.samples, local, plan.texels.seams)
                else:
                    values = local if plan.points.scatter is None else local[plan.points.scatter]
            bounced = None
            if self.bounce is not None:
                world = self.bounce.bounced[id(plan)]
                bounced = np.stack(
                    [frames.to_local_frame(world[:, c], plan.matrix[:3, :3]) for c in range(world.shape[1])], axis=1
                )
                if plan.texels is not None:  # (res, res, C, n*n): each channel's image as the direct one's
                    images = [
                        texel_image(plan.texels.samples, bounced[:, c], plan.texels.seams) for c in range(len(world[0]))
                    ]
                    bounced = np.stack(images, axis=2)
                elif plan.points.scatter is not None:
                    bounced = bounced[plan.points.scatter]
            result = comp.result()
            errors.append(result.error.astype(np.float64))
            square_norm_sum += result.square_norm_sum()
            record = bake_record(s, plan, backend, stats, result)
            if plan.texels is not None:
                texel_extra = (plan.texels.uv_name, plan.texels.created_uvs, bounced, back_values(plan))
                items.append((plan.mesh, values, "TEXEL", record, texel_extra))
            else:
                items.append((plan.mesh, values, plan.points.domain, record, bounced, back_values(plan)))
        storage.write_bakes(items)
        err = np.concatenate(errors)
        rep.ok = True
        rep.objects = [p.name for p in self.plans]
        rep.backend = backends.pop() if backends else "NONE"
        if rep.backend == "BVHTREE" and s.backend == "AUTO":
            rep.note = fallback_note()
        rep.seconds = time.perf_counter() - self.started
        rep.rays_traced = stats_all.rays_traced
        rep.rays_skipped, rep.rays_blocked = stats_all.rays_skipped, stats_all.occluded_rays
        rep.estimate_seconds, rep.estimate_bytes = self.estimate.seconds, self.estimate.bytes
        rep.skipped_below_horizon = stats_all.skipped_below_horizon
        rep.skipped_unoccludable = stats_all.skipped_unoccludable
        rep.skipped_shadows_off = stats_all.skipped_shadows_off
        above = front.rays_traced + front.skipped_unoccludable + front.skipped_shadows_off
        rep.enclosed_share = front.occluded_rays / above if above else 0.0  # (back sides face outwards)
        rep.points = int(len(err))
        rep.texels = sum(len(p.texels.samples.texels) for p in self.plans if p.texels is not None)
        rep.texels_interpolated = sum(getattr(p.computation, "interpolated", 0) for p in self.plans)
        rep.error_estimate = float(np.sqrt(np.mean(err**2))) if len(err) else 0.0
        rms_norm = float(np.sqrt(square_norm_sum / len(err))) if len(err) else 0.0
        rep.error_estimate_relative = rep.error_estimate / rms_norm if rms_norm > 0 else 0.0
        if self.bounce is not None:
            rep.bounces, rep.bounce_channels = s.bounces, self.bounce.channels
            rep.bounce_points, rep.albedo_notes = self.bounce_points, list(self.bounce.notes)
        rep.message = rep.summary_lines()[0]
        return rep

    def run(self, progress=None):
        """Compute and write; progress(fraction, text) after each chunk (an exception aborts)."""
        for fraction, text in self.steps():
            if progress is not None:
                progress(fraction, text)
        return self.finish()


def bake(
    objects,
    order=4,
    samples=256,
    shadows=True,
    backend="AUTO",
    direction_set="FIBONACCI",
    seed=0,
    self_shadow_only=False,
    progress=None,
    cull=True,
    depsgraph=None,
    chunk_rays=transfer.CHUNK_RAYS,
    threads=None,
    bounces=0,
    target="VERTICES",
    uv_map=None,
    resolution=None,
    texel_density=20.0,
    adaptive=adaptive.TOLERANCE,
):
    """Bake and write; returns a BakeReport. Raises BakeError when nothing can be baked."""
    if objects is not None and isinstance(objects, bpy.types.Object):
        objects = [objects]
    settings = BakeSettings(
        order,
        samples,
        direction_set,
        seed,
        shadows,
        self_shadow_only,
        backend,
        cull,
        chunk_rays,
        threads,
        bounces,
        target,
        uv_map,
        resolution,
        texel_density,
        adaptive,
    )
    job = BakeJob(objects, settings, depsgraph)
    return job.run(progress)


def status(obj, use_cache=False):
    """('fresh' | 'stale' | 'none', reason) for an object."""
    if obj is None or getattr(obj, "type", None) != "MESH":
        return "none", "not a mesh object"
    state, reason = storage.bake_status(obj.data, use_cache=use_cache)
    return state.lower(), reason
