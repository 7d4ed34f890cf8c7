"""Accuracy report: error against run time, direction sets, the bake's error estimate,
ringing windows on stiff lighting, and the float32 storage error. Writes docs/accuracy.md and
docs/images/accuracy_*.png; every number in them is measured by this command.

    .venv/bin/python benchmarks/accuracy_report.py            # full run, ~10-15 min on 2 cores
    .venv/bin/python benchmarks/accuracy_report.py --quick    # smoke run (few settings, ~2 min)
    .venv/bin/python benchmarks/accuracy_report.py --from-json benchmarks/accuracy_results.json
                                                              # rewrite the docs from saved numbers
    .venv/bin/python benchmarks/accuracy_report.py --only-split   # re-measure the light split section

The light split section (every bundled HDRI, with and without the split, against Cycles and a
brute-force quadrature) is benchmarks/accuracy_split.py; its Cycles and brute-force references are
cached in benchmarks/accuracy_references.json and reused while the scene and settings match.

Scenes (benchmarks/accuracy_scenes.py; object transforms are the identity, so the local and world
frames agree):
  suzanne: Suzanne subdivided once (Subdivision level 1), smooth, standing on a ground grid;
  torus:   a smooth torus (R 1, r 0.4, 48 x 24) tilted 50 degrees, standing on the same grid.
Error measure: relative RMSE of luminance Y = 0.2126 R + 0.7152 G + 0.0722 B over all vertices of
the scene (object and ground), sqrt(mean (Y - Y_ref)^2) / sqrt(mean Y_ref^2), radiance clamped at
zero as the display does (api.shade). The PRT radiance is exactly what api.shade returns (checked
in the run).
  * Monte-Carlo (MC) error: against a converged bake of the same order (65 536 Fibonacci
    directions; the lower orders of one bake are the first n^2 coefficients of the highest).
  * total error: against Cycles' DIFFUSE bake with pass_filter {'DIRECT'} (E / pi, the same
    quantity) at CYCLES_REF samples, so it includes the SH band limit.
Cycles' own time and error at CYCLES_CURVE samples are measured in the same run, against the
same reference (independent seeds).
"""

import argparse
import json
import math
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import numpy as np
from accuracy_scenes import (
    BACKGROUND,
    CAP_AXIS,
    build_scene,
    cap_truth,
    cycles_bake,
    prt_bake,
    radiance,
    scene_points,
    set_world,
    transfer_float64,
)

from prt_addon.core.sh.resample import LUMINANCE as LUMA

FULL = dict(
    orders=[2, 3, 4, 6, 8],
    samples=[64, 128, 256, 512, 1024, 2048, 4096],
    sets=["FIBONACCI", "STRATIFIED", "UNIFORM"],
    converged=65536,
    hdris=["forest", "city", "sunrise"],
    all_hdris=["city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset"],
    cycles_ref=1024,
    cycles_curve=[16, 64, 256],
    scenes=["suzanne", "torus"],
    caps_deg=[0.5, 1.0, 2.0, 5.0],
    caps_radiance=[1e4, 1e5, 1e6],
    f32_samples=1024,
)
QUICK = dict(
    FULL,
    orders=[2, 4, 8],
    samples=[64, 256],
    sets=["FIBONACCI", "UNIFORM"],
    converged=8192,
    hdris=["forest", "city"],
    all_hdris=["city", "forest", "sunrise"],
    cycles_ref=128,
    cycles_curve=[16],
    split_hdris=["city", "sunrise"],
    split_cycles=128,
    scenes=["suzanne"],
    caps_deg=[0.5, 5.0],
    caps_radiance=[1e4, 1e6],
    f32_samples=256,
)
WINDOWS = ["NONE", "HANNING", "LANCZOS", "AUTO_LAPLACIAN", "AUTO_HANNING"]


def log(*args):
    print(time.strftime("%H:%M:%S"), *args, flush=True)


def rel_err(y, ref):
    return float(np.sqrt(np.mean((y - ref) ** 2)) / np.sqrt(np.mean(ref**2)))


# --- windows -----------------------------------------------------------------------------------


def windowed(light, kind):
    import windows

    n = int(round(math.sqrt(light.shape[0])))
    if kind == "NONE":
        return light, ""
    if kind in ("HANNING", "LANCZOS"):
        return windows.apply_window(light, windows.window_weights(kind, n, n)), f"width {n}"
    res = windows.auto_window(light, kind.split("_")[1])
    label = f"lambda {res.param:.3g}" if res.kind == "LAPLACIAN" else f"width {res.param:.3g}"
    return windows.apply_window(light, res.weights), label


def ringing_row(transfer, light, truth_y):
    """Unclamped radiance: negative fraction (vertices with any channel < 0), min / mean Y_truth;
    errors of the clamped and unclamped luminance against the truth (None without truth)."""
    u = transfer[:, : light.shape[0]].astype(np.float64) @ light
    mean = float(np.mean(truth_y)) if truth_y is not None else float(np.mean(np.maximum(u, 0) @ LUMA))
    row = {
        "neg_fraction": float(np.mean(np.any(u < 0, axis=1))),
        "min_rel": float(u.min() / mean),
        "finite": bool(np.all(np.isfinite(u))),
    }
    if truth_y is not None:
        row["err_clamped"] = rel_err(np.maximum(u, 0) @ LUMA, truth_y)
        row["err_unclamped"] = rel_err(u @ LUMA, truth_y)
    return row


# --- the run -----------------------------------------------------------------------------------


def run(cfg, cache, only_split=False):
    """Every section's numbers; only_split measures the light split section alone."""
    import accuracy_split
    import bpy

    import prt_addon
    from prt_addon import api
    from prt_addon.core.sh import analytic
    from prt_addon.core.transfer import quadrature as transfer

    prt_addon.register()
    results = {"config": cfg, "scenes": {}, "machine": os.uname().nodename, "started": time.ctime()}
    max_order = max(cfg["orders"])
    for scene_name in [] if only_split else cfg["scenes"]:
        objs = build_scene(bpy, scene_name)
        scene = bpy.context.scene
        nverts = [len(o.data.vertices) for o in objs]
        res = results["scenes"][scene_name] = {"vertices": nverts, "bakes": [], "cycles": {}, "lights": {}}
        log(scene_name, "vertices", nverts)
        # Lighting per HDRI and order (projected through the add-on, as a user would), SH only:
        # these sections measure the SH itself (the light split has its own section).
        lights = {}
        for hdri in cfg["all_hdris"]:
            set_world(bpy, scene, hdri)
            lights[hdri] = {n: api.project_world(scene, n, split_lights=False) for n in cfg["orders"]}
        # Cycles reference and curve.
        truth = {}
        for hdri in cfg["hdris"]:
            set_world(bpy, scene, hdri)
            secs, ref = cycles_bake(bpy, scene, objs, cfg["cycles_ref"], seed=1)
            truth[hdri] = ref @ LUMA
            curve = []
            for i, s in enumerate(cfg["cycles_curve"]):
                sec, img = cycles_bake(bpy, scene, objs, s, seed=100 + i)
                curve.append(
                    {
                        "samples": s,
                        "seconds": sec,
                        "error": rel_err(img @ LUMA, truth[hdri]),
                        "min": float(img.min()),
                        "finite": bool(np.all(np.isfinite(img))),
                    }
                )
            res["cycles"][hdri] = {"ref_samples": cfg["cycles_ref"], "ref_seconds": secs, "curve": curve}
            log(
                scene_name,
                hdri,
                "cycles ref",
                f"{secs:.1f}s",
                [(c["samples"], round(c["seconds"], 1), round(c["error"], 4)) for c in curve],
            )
        # Converged PRT transfer.
        sec, rep, conv = prt_bake(objs, max_order, cfg["converged"], "FIBONACCI")
        res["converged"] = {"samples": cfg["converged"], "seconds": sec}
        log(scene_name, "converged bake", f"{sec:.1f}s")
        # Check: our radiance is what api.shade returns.
        set_world(bpy, scene, cfg["hdris"][0])
        api.project_world(scene, max_order, split_lights=False)
        shade = np.concatenate([api.shade(o, scene) for o in objs])
        check = float(np.abs(shade - radiance(conv, lights[cfg["hdris"][0]][max_order])).max() / shade.max())
        res["shade_check"] = check
        assert check < 1e-5, check
        conv_y = {h: {n: radiance(conv, lights[h][n]) @ LUMA for n in cfg["orders"]} for h in cfg["hdris"]}
        res["band_limit"] = {h: {str(n): rel_err(conv_y[h][n], truth[h]) for n in cfg["orders"]} for h in cfg["hdris"]}
        # Sweep.
        for kind in cfg["sets"]:
            for n in cfg["orders"]:
                tc = conv[:, : n * n].astype(np.float64)
                tc_norm = float(np.sqrt(np.mean(np.sum(tc**2, axis=1))))
                for s in cfg["samples"]:
                    sec, rep, t = prt_bake(objs, n, s, kind)
                    true_err = float(np.sqrt(np.mean(np.sum((t - tc) ** 2, axis=1))))
                    row = {
                        "set": kind,
                        "order": n,
                        "samples": s,
                        "seconds": sec,
                        "calibration": transfer.error_calibration(kind, s, n),
                        "rays": rep.rays_traced,
                        "estimate": rep.error_estimate,
                        "true_transfer_error": true_err,
                        "transfer_rel_error": true_err / tc_norm,
                        "mc": {},
                        "total": {},
                    }
                    for h in cfg["hdris"]:
                        y = radiance(t, lights[h][n]) @ LUMA
                        row["mc"][h] = rel_err(y, conv_y[h][n])
                        row["total"][h] = rel_err(y, truth[h])
                    res["bakes"].append(row)
                log(
                    scene_name,
                    kind,
                    "order",
                    n,
                    "done",
                    [
                        (r["samples"], round(r["seconds"], 2), round(r["mc"][cfg["hdris"][0]], 4))
                        for r in res["bakes"][-len(cfg["samples"]) :]
                    ],
                )
        # Float32 storage error.
        points = scene_points(bpy, objs)
        t64 = transfer_float64(points, max_order, cfg["f32_samples"])
        t32 = t64.astype(np.float32).astype(np.float64)
        f32 = {
            "samples": cfg["f32_samples"],
            "coeff_rel": float(np.abs(t32 - t64).max() / np.abs(t64).max()),
            "rows": [],
        }
        stored = prt_bake(objs, max_order, cfg["f32_samples"], "FIBONACCI")[2].astype(np.float64)
        f32["stored_vs_float64"] = float(np.abs(stored - t64).max() / np.abs(t64).max())
        for h in cfg["hdris"]:
            for n in cfg["orders"]:
                y64 = np.maximum(t64[:, : n * n] @ lights[h][n], 0) @ LUMA
                y32 = np.maximum(t32[:, : n * n] @ lights[h][n], 0) @ LUMA
                mc = next(
                    r["mc"][h]
                    for r in res["bakes"]
                    if r["set"] == "FIBONACCI"
                    and r["order"] == n
                    and r["samples"] == max(s for s in cfg["samples"] if s <= cfg["f32_samples"])
                )
                f32["rows"].append({"hdri": h, "order": n, "f32_error": rel_err(y32, y64), "mc_error": mc})
        res["float32"] = f32
        log(scene_name, "float32", f32["coeff_rel"], f32["stored_vs_float64"])
        # Stiff cases: windows on the converged transfer.
        stiff = []
        t0_conv = conv[:, 0].astype(np.float64)
        for h in cfg["all_hdris"]:
            for n in cfg["orders"]:
                for w in WINDOWS:
                    lw, label = windowed(lights[h][n], w)
                    row = ringing_row(conv, lw, truth.get(h))
                    row.update(case=h, order=n, window=w, param=label)
                    stiff.append(row)
        for deg in cfg["caps_deg"]:
            for value in cfg["caps_radiance"]:
                ty = cap_truth(points, t0_conv, math.radians(deg), value)
                for n in cfg["orders"]:
                    light = analytic.cap_coeffs(n, CAP_AXIS, math.radians(deg), value)
                    light = np.repeat(np.asarray(light).reshape(-1, 1), 3, axis=1)
                    light[0] += BACKGROUND * math.sqrt(4 * math.pi)
                    for w in WINDOWS:
                        lw, label = windowed(light, w)
                        row = ringing_row(conv, lw, ty)
                        row.update(case=f"cap {deg:g} deg x {value:.0e}", order=n, window=w, param=label)
                        stiff.append(row)
        res["stiff"] = stiff
        log(scene_name, "stiff rows", len(stiff))
    # HDRI peaks (for the text).
    peaks = {}
    for h in cfg["all_hdris"]:
        img = bpy.data.images.load(
            os.path.join(bpy.utils.system_resource("DATAFILES", path="studiolights/world"), f"{h}.exr"),
            check_existing=True,
        )
        px = np.empty(img.size[0] * img.size[1] * img.channels, np.float32)
        img.pixels.foreach_get(px)
        rgb = px.reshape(-1, img.channels)[:, :3]
        peaks[h] = {"peak": float(np.nanmax(rgb)), "mean": float(np.nanmean(rgb @ LUMA.astype(np.float32)))}
    results["hdri_peaks"] = peaks
    results["split"] = accuracy_split.run(bpy, cfg, cache, log)
    results["finished"] = time.ctime()
    return results


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--only-split", action="store_true", help="measure the light split section, keep the rest")
    ap.add_argument("--references", default=os.path.join(ROOT, "benchmarks", "accuracy_references.json"))
    ap.add_argument("--from-json")
    ap.add_argument("--json", default=os.path.join(ROOT, "benchmarks", "accuracy_results.json"))
    ap.add_argument("--docs", default=os.path.join(ROOT, "docs"))
    args = ap.parse_args()
    if args.from_json:
        with open(args.from_json) as f:
            results = json.load(f)
    else:
        t_start = time.perf_counter()
        cache = json.load(open(args.references)) if os.path.isfile(args.references) else {}
        import accuracy_split

        accuracy_split.IMAGES_DIR = os.path.join(args.docs, "images")
        results = run(QUICK if args.quick else FULL, cache, args.only_split)
        if args.only_split:  # the other sections from the saved run
            with open(args.json) as f:
                results = dict(json.load(f), split=results["split"])
            results["split_seconds"] = time.perf_counter() - t_start
        else:
            results["wall_seconds"] = time.perf_counter() - t_start
        with open(args.references, "w") as f:
            json.dump(cache, f)
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1)
        log("saved", args.json)
    import accuracy_docs

    accuracy_docs.write(results, args.docs)
