"""The bake's estimate of its time and memory against what the bake then takes, on bakes of different kinds.

Run from the repository root:  .venv/bin/python benchmarks/bench_estimate.py [--quick] [--threads N]

Each case runs in a fresh Python: api.estimate_bake, then the same api.bake, timed, with its peak
resident memory over the scene's (VmHWM minus VmRSS before the bake) and the peak of the numpy
and Python allocations (tracemalloc, on a second bake of the same scene). Prints estimated /
measured side by side; the estimate is an upper bound on memory and a guess on time (its
constants: prt_addon/blender/bake/estimate.py, docs/bake.md "Estimates").
"""

import argparse
import os
import sys
import time
import tracemalloc

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))
sys.path.insert(0, os.path.join(ROOT, "tests"))

import bpy
from bench_bake import build_scene, child_line, vm_kib, wavy_grid

import prt_addon
from prt_addon import api


def _texel_room(resolution, **options):
    from helpers import texel_scenes

    bpy.ops.wm.read_factory_settings(use_empty=True)
    objs = texel_scenes.low_poly_room(bpy)
    options.update(target="TEXELS", resolution=resolution, uv_map=texel_scenes.LIGHTMAP)
    return objs, options


def _skylight_room():
    from helpers.skylight_room import skylight_room

    bpy.ops.wm.read_factory_settings(use_empty=True)
    return skylight_room(bpy, bpy.context.scene, hdri=None)


CASES = {
    "vertex": lambda q: (build_scene(*((2, 60) if q else (3, 150))), {"order": 4, "samples": 256}),
    "vertex-o8": lambda q: (build_scene(*((2, 60) if q else (3, 150))), {"order": 8, "samples": 512}),
    "vertex-3b": lambda q: (build_scene(*((2, 60) if q else (3, 150))), {"order": 4, "samples": 256, "bounces": 3}),
    "room-4b": lambda q: (_skylight_room(), {"order": 4, "samples": 256, "bounces": 4}),
    "grid-3b": lambda q: ([wavy_grid(200 if q else 500)], {"order": 4, "samples": 256, "bounces": 3}),
    "texel": lambda q: _texel_room(32 if q else 64, order=4, samples=256),
    "texel-all": lambda q: _texel_room(32 if q else 64, order=4, samples=256, adaptive=0.0),
    "texel-3b": lambda q: _texel_room(32 if q else 64, order=4, samples=256, bounces=3),
}


def child(name, quick, threads):
    prt_addon.register()
    objs, options = CASES[name](quick)
    options["threads"] = threads
    found = api.estimate_bake(objs, **options)
    before = vm_kib("VmRSS")
    started = time.perf_counter()
    report = api.bake(objs, **options)
    seconds = time.perf_counter() - started
    peak = vm_kib("VmHWM")
    tracemalloc.start()
    api.bake(objs, **options)
    traced = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    points = report.points + report.bounce_points
    print(
        f"0 {points} {found['seconds']:.3f} {seconds:.3f} {found['bytes']} {(peak - before) * 1024} {traced} "
        f"{report.rays_traced + report.rays_skipped} {found['rays']}"
    )


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--child", default="")
    parser.add_argument("cases", nargs="*", default=list(CASES))
    args = parser.parse_args()
    if args.child:
        child(args.child, args.quick, args.threads)
        return
    print(f"{os.cpu_count()} cores, {args.threads} threads; MB = 2^20 bytes")
    print(
        f"{'case':10s} {'points':>8s} {'est s':>7s} {'bake s':>7s} {'ratio':>6s} {'est MB':>7s} {'peak MB':>8s}"
        f" {'ratio':>6s} {'numpy MB':>8s} {'ratio':>6s} {'rays est/bake':>13s}"
    )
    for name in args.cases:
        extra = ["--quick"] if args.quick else []
        fields = child_line(__file__, "--child", name, "--threads", args.threads, *extra)
        if fields is None:
            continue
        _zero, points, est_s, bake_s, est_b, peak_b, traced_b, rays, est_rays = fields
        est_s, bake_s = float(est_s), float(bake_s)
        est_b, peak_b, traced_b = (int(v) / 2**20 for v in (est_b, peak_b, traced_b))
        print(
            f"{name:10s} {int(points):8d} {est_s:7.2f} {bake_s:7.2f} {est_s / bake_s:6.2f} {est_b:7.0f} {peak_b:8.0f}"
            f" {est_b / max(peak_b, 1e-9):6.2f} {traced_b:8.0f} {est_b / max(traced_b, 1e-9):6.2f}"
            f" {int(est_rays) / max(int(rays), 1):13.2f}"
        )


if __name__ == "__main__":
    main()
