"""Benchmark of interreflected bakes: bounces against the direct bake, side by side. Run from the
repository root:

    .venv/bin/python benchmarks/bench_bounce.py            # bench_bake's scene, then 1M-vertex memory
    .venv/bin/python benchmarks/bench_bounce.py --quick    # smaller scene, smaller memory grid
    .venv/bin/python benchmarks/bench_bounce.py --no-memory --repeats 15    # the speed part only
    .venv/bin/python benchmarks/bench_bounce.py --room --no-memory    # an enclosed room instead
    .venv/bin/python benchmarks/bench_bounce.py --room --no-memory --front-only    # its walls' back sides not baked

Prints, on bench_bake.py's scene (subdivided Suzanne on a ground grid), medians [min - max] of
interleaved repeats of the whole api.bake call with bounces = 0, 1 and 3 and their ratios to the
direct bake (target: 3 bounces at most 1.5 times the direct bake), the time of the shadow pass's
two queries on all of the bake's own rays (Embree's OCCLUDED, which a direct bake uses, and
INTERSECT for the nearest triangle, which a bounced bake asks on half of them), and the peak
memory (VmHWM) of a direct and a 3-bounce bake of a 1M-vertex wavy grid in fresh processes.
With --room the scene is an enclosed room instead (a closed box of inward-facing grids with a
skylight, the same Suzanne inside): most rays hit a wall, so every
bounce pass has about as many entries as there are hit-traced rays. The room's walls are open
grids, so both bakes also bake their back sides (direct light only, the same work in both);
--front-only leaves the back sides out, as for a room made of closed meshes. Besides the wall
time, each bake's CPU time (every thread's, time.process_time) and its ratio are printed: on
this shared machine the wall time moves with the other processes' load far more than the CPU
time does.
"""

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))


import bpy
from bench_bake import build_scene, child_line, same_rays, spread, vm_kib, wavy_grid

import prt_addon
from prt_addon import api
from prt_addon.blender.bake import job as bake_job
from prt_addon.core.trace import raytrace


def query_seconds(occ, batches):
    """(OCCLUDED seconds, INTERSECT seconds) over the bake's batches, one thread each."""
    times = []
    for query in ("occluded", "nearest_triangles"):
        t0 = time.perf_counter()
        for origins, dirs in batches:
            getattr(occ, query)(origins, dirs)
        times.append(time.perf_counter() - t0)
    return times


def enclosed_room(subdiv, cuts):
    """A 6 x 6 x 4 m box of inward-facing cuts x cuts grids (floor, four walls, a ceiling with a
    1 x 1 m skylight) around bench_bake's Suzanne (the bake's time does not depend on the light)."""
    import bmesh  # (only once bpy is imported)

    objects = build_scene(subdiv, 2)
    ground = objects.pop()
    bpy.data.objects.remove(ground)
    faces = {
        "floor": ((0, 0, 0), (0, 0, 0)),
        "ceiling": ((0, 0, 4), (np.pi, 0, 0)),
        "wall_x0": ((-3, 0, 2), (0, np.pi / 2, 0)),
        "wall_x1": ((3, 0, 2), (0, -np.pi / 2, 0)),
        "wall_y0": ((0, -3, 2), (-np.pi / 2, 0, 0)),
        "wall_y1": ((0, 3, 2), (np.pi / 2, 0, 0)),
    }
    for name, (location, rotation) in faces.items():
        bpy.ops.mesh.primitive_grid_add(
            x_subdivisions=cuts, y_subdivisions=cuts, size=6, location=location, rotation=rotation
        )
        obj = bpy.context.object
        obj.name = name
        if name == "ceiling":
            bm = bmesh.new()
            bm.from_mesh(obj.data)
            hole = [f for f in bm.faces if abs(f.calc_center_median().x) < 0.5 and abs(f.calc_center_median().y) < 0.5]
            bmesh.ops.delete(bm, geom=hole, context="FACES")
            bm.to_mesh(obj.data)
            bm.free()
        objects.append(obj)
    return objects


def speed(args):
    objects = enclosed_room(args.subdiv, args.cuts) if args.room else build_scene(args.subdiv, args.grid)
    if args.front_only:  # (the job's back-side step made to find no open mesh)
        bake_job.back_computation = lambda job, plan: None
    points = sum(len(o.data.vertices) for o in objects)
    kind = "enclosed room" if args.room else "Suzanne on a ground grid"
    print(f"scene: {kind}, {points:,} vertices, order {args.order}, {args.samples} directions, {args.threads} threads")
    warm = api.bake(objects, order=args.order, samples=args.samples, threads=args.threads)
    print(f"  rays that hit a surface: {warm.rays_blocked / max(1, warm.rays_traced):.2f} of those traced")
    runs = {b: [] for b in (0, 1, 3)}
    cpu = {b: [] for b in runs}
    reports = {}
    for _ in range(args.repeats):
        for bounces in runs:
            t0, c0 = time.perf_counter(), time.process_time()
            reports[bounces] = api.bake(
                objects, order=args.order, samples=args.samples, bounces=bounces, threads=args.threads
            )
            runs[bounces].append(time.perf_counter() - t0)
            cpu[bounces].append(time.process_time() - c0)
    print(f"  load average {os.getloadavg()[0]:.1f} at the end of the bakes")
    for bounces, seconds in runs.items():
        ratios = [s / d for s, d in zip(seconds, runs[0])]
        cpu_ratios = [s / d for s, d in zip(cpu[bounces], cpu[0])]
        extra = f", passes {reports[bounces].bounce_seconds:.2f} s" if bounces else ""
        if bounces:  # this machine is noisy: three estimates of one ratio
            extra += (
                f"; ratio of medians {np.median(seconds) / np.median(runs[0]):.3f},"
                f" of minima {min(seconds) / min(runs[0]):.3f}"
            )
        print(f"  bounces={bounces}: {spread(seconds)} s, / direct {spread(ratios)}{extra}")
        print(f"    CPU time {spread(cpu[bounces])} s, / direct {spread(cpu_ratios)}")
    vertices, triangles, _o, _d, batches = same_rays(objects, args.samples)
    occ = raytrace.EmbreeOccluder(vertices, triangles)
    occluded, intersect = [], []
    for _ in range(3):
        a, b = query_seconds(occ, batches)
        occluded.append(a)
        intersect.append(b)
    rays = sum(len(o) for o, _d in batches)
    print(
        f"  shadow-pass query on the bake's {rays:,} rays (one thread): OCCLUDED {spread(occluded)} s, "
        f"INTERSECT (nearest triangle) {spread(intersect)} s, ratio {spread([b / a for a, b in zip(occluded, intersect)])}"
    )


def memory_child(bounces, side):
    prt_addon.register()
    grid = wavy_grid(side)
    before = vm_kib("VmRSS")
    report = api.bake([grid], order=4, samples=256, bounces=bounces)
    peak = vm_kib("VmHWM")
    print(f"{len(grid.data.vertices)} {bounces} {before} {peak} {report.rays_traced} {report.seconds:.2f}")


def memory(args):
    print(f"peak memory, {args.side**2:,}-vertex wavy grid (order 4, 256 directions), fresh process per run:")
    for bounces in (0, 3):
        fields = child_line(__file__, "--memory-child", bounces, "--side", args.side)
        if fields is None:
            continue
        verts, b, before, peak, rays, seconds = fields
        print(
            f"  bounces={b}: {int(verts):,} vertices, peak {int(peak) / 1024:.0f} MiB "
            f"(+{(int(peak) - int(before)) / 1024:.0f} MiB over the scene), {int(rays):,} rays, {seconds} s"
        )


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--samples", type=int, default=256)
    parser.add_argument("--order", type=int, default=4)
    parser.add_argument("--threads", type=int, default=None)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--memory-child", type=int, default=-1)
    parser.add_argument("--side", type=int, default=1000)
    parser.add_argument("--no-memory", action="store_true", help="skip the 1M-vertex memory runs")
    parser.add_argument("--room", action="store_true", help="an enclosed room: most rays hit a wall")
    parser.add_argument("--front-only", action="store_true", help="no back sides (as if every mesh were closed)")
    parser.add_argument("--cuts", type=int, default=60, help="--room: each wall's grid subdivisions")
    args = parser.parse_args()
    if args.memory_child >= 0:
        memory_child(args.memory_child, args.side)
        return
    args.subdiv, args.grid = (2, 60) if args.quick else (3, 150)
    if args.quick:
        args.side, args.repeats = 300, 3
    prt_addon.register()
    speed(args)
    if not args.no_memory:
        memory(args)


if __name__ == "__main__":
    main()
