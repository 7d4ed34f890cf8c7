"""Texel bakes: time against raw Embree tracing the same rays, texels/s and rays/s, peak memory at 2048 x 2048, frame cost against vertex bakes.

Run after the test command has made the venv:  .venv/bin/python benchmarks/bench_texel_bake.py
(--no-memory, --no-frame, --resolutions 64 128). Ratios are measured side by side in one run, for
every texel traced and for the adaptive default; 2-core figures are
noisy, so each ratio is the median of --repeats pairs.
"""

import argparse
import os
import resource
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))

import bpy
import numpy as np
from bench_bake import raw_batches_seconds  # (benchmarks/: the same raw tracing)

import prt_addon
from prt_addon import api
from prt_addon.blender.bake import job as bake_job, settings as bake_settings
from prt_addon.blender.scene import lighting, parts as scene_parts
from prt_addon.core.trace import raytrace
from prt_addon.core.transfer import mesh as core_mesh

SKY = np.zeros((16, 3))
SKY[0] = np.sqrt(4.0 * np.pi)
SKY[2] = 1.0


def room(res):
    from helpers import texel_scenes

    bpy.ops.wm.read_factory_settings(use_empty=True)
    objs = texel_scenes.low_poly_room(bpy)
    lighting.set_light_override(bpy.context.scene, SKY)
    return objs, dict(order=4, samples=256, target="TEXELS", resolution=res, uv_map=texel_scenes.LIGHTMAP)


def bake_seconds(objs, options, threads):
    """(wall seconds, process CPU seconds, report) of one bake."""
    c0, t0 = time.process_time(), time.perf_counter()
    report = api.bake(objs, threads=threads, **options)
    return time.perf_counter() - t0, time.process_time() - c0, report


def raw_seconds(objs, options, threads):
    """Embree alone on the bake's own ray batches, the same threads, a BVH built beforehand."""
    settings = bake_settings.BakeSettings(backend="EMBREE", threads=threads, **options)
    job = bake_job.BakeJob(objs, settings)
    batches = [b for plan in job.plans for b in plan.computation.iter_rays()]
    job.close()
    parts = scene_parts.scene_parts(bpy.context.evaluated_depsgraph_get())
    occ = raytrace.EmbreeOccluder(*core_mesh.concatenate_parts(parts))
    c0 = time.process_time()
    wall = raw_batches_seconds(occ, batches, threads)
    return wall, time.process_time() - c0, sum(len(o) for o, _d in batches)


def speed(res, threads, repeats):
    """Tracing every texel (adaptive=0) and the adaptive default, each against raw Embree on its
    own rays, and the adaptive bake against raw Embree on every texel's rays; pairs interleaved."""
    objs, options = room(res)
    full = dict(options, adaptive=0.0)
    names = ("full", "adaptive", "raw full", "raw adaptive")
    runs = {name: [] for name in names}
    cpu = {name: [] for name in names}  # process CPU seconds (less sensitive to other jobs)
    load = os.getloadavg()[0]
    for _ in range(repeats):
        raw_full, raw_full_cpu, rays_full = raw_seconds(objs, full, threads)
        seconds_full, full_cpu, report_full = bake_seconds(objs, full, threads)
        raw_adaptive, raw_adaptive_cpu, rays_adaptive = raw_seconds(objs, options, threads)
        seconds, adaptive_cpu, report = bake_seconds(objs, options, threads)
        for name, value, used in zip(
            names,
            (seconds_full, seconds, raw_full, raw_adaptive),
            (full_cpu, adaptive_cpu, raw_full_cpu, raw_adaptive_cpu),
        ):
            runs[name].append(value)
            cpu[name].append(used)
    med = {name: statistics.median(values) for name, values in runs.items()}
    ratio = lambda a, b: statistics.median(x / y for x, y in zip(runs[a], runs[b]))
    listing = lambda a, b: ", ".join(f"{x / y:.2f}" for x, y in zip(runs[a], runs[b]))
    cpu_ratio = lambda a, b: statistics.median(x / y for x, y in zip(cpu[a], cpu[b]))
    print(
        f"room, {len(objs)} objects, {res} x {res} texels each, order 4, 256 directions, {threads} threads "
        f"({repeats} pairs; load average {load:.1f} before, {os.getloadavg()[0]:.1f} after):"
    )
    for name, rep, rays, key in (
        ("every texel", report_full, rays_full, "full"),
        ("adaptive", report, rays_adaptive, "adaptive"),
    ):
        print(
            f"  {name}: texels {rep.texels:,} ({rep.texels_interpolated:,} interpolated), rays traced "
            f"{rep.rays_traced:,} (raw batches {rays:,}); bake {med[key]:.3f} s: {rep.texels / med[key]:,.0f} "
            f"texels/s, {rep.rays_traced / med[key]:,.0f} rays/s"
        )
    print(
        f"  raw Embree on every texel's rays {med['raw full']:.3f} s, on the adaptive bake's {med['raw adaptive']:.3f} s"
    )
    print(
        f"  every texel / raw Embree (same rays): median {ratio('full', 'raw full'):.2f} ({listing('full', 'raw full')})"
    )
    print(
        f"  adaptive / raw Embree (same rays): median {ratio('adaptive', 'raw adaptive'):.2f} ({listing('adaptive', 'raw adaptive')})"
    )
    print(
        f"  adaptive / raw Embree on every texel's rays: median {ratio('adaptive', 'raw full'):.2f} "
        f"({listing('adaptive', 'raw full')}); rays {report.rays_traced / report_full.rays_traced:.2f} of every texel's"
    )
    print(
        f"  process CPU time, bake / raw Embree (same rays): every texel {cpu_ratio('full', 'raw full'):.2f}, "
        f"adaptive {cpu_ratio('adaptive', 'raw adaptive'):.2f}"
    )


def memory_child(res, order):
    objs, options = room(16)
    floor = objs[0]
    options.update(order=order, resolution=res, samples=16)  # (memory hardly depends on the directions)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t0 = time.perf_counter()
    report = api.bake([floor], **options)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    estimate = bake_settings.texel_memory(res, order)
    print(
        f"{res} x {res} texels, order {order}: {report.texels:,} texels in {time.perf_counter() - t0:.1f} s, "
        f"peak RSS {peak / 2**20:.2f} GiB (before the bake {before / 2**20:.2f} GiB), "
        f"estimate {estimate / 2**30:.2f} GiB"
    )


def frame_cost(frames):
    from prt_addon.blender.display import offscreen

    objs, options = room(64)
    scene = bpy.context.scene
    bpy.ops.object.camera_add(location=(4.0, -6.0, 3.0), rotation=(1.2, 0.0, 0.6))
    scene.camera = bpy.context.object
    assert offscreen.ensure_gpu()
    times = {}
    for target in ("VERTICES", "TEXELS"):
        api.bake(objs, **dict(options, target=target))
        api.render_view(scene, 512, 512)  # (uploads)
        t0 = time.perf_counter()
        for _ in range(frames):
            api.render_view(scene, 512, 512)
        times[target] = (time.perf_counter() - t0) / frames
    print(
        f"frame at 512 x 512 (render_view, the room, order 4): vertices {1e3 * times['VERTICES']:.1f} ms, "
        f"texels (64 x 64 each) {1e3 * times['TEXELS']:.1f} ms, ratio {times['TEXELS'] / times['VERTICES']:.2f}"
    )


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--no-memory", action="store_true")
    parser.add_argument("--no-frame", action="store_true")
    parser.add_argument("--resolutions", type=int, nargs="+", default=[64, 128])
    parser.add_argument("--memory-child", nargs=2, type=int, metavar=("RES", "ORDER"))
    args = parser.parse_args()
    prt_addon.register()
    if args.memory_child:
        memory_child(*args.memory_child)
        return
    for res in args.resolutions:
        speed(res, args.threads, args.repeats)
    if not args.no_frame:
        frame_cost(5)
    if not args.no_memory:
        for res, order in ((1024, 8), (2048, 4), (2048, 8)):
            subprocess.run([sys.executable, __file__, "--memory-child", str(res), str(order)], check=True)


if __name__ == "__main__":
    main()
