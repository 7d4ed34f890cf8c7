"""Tables, plots and text of docs/accuracy.md from the numbers of benchmarks/accuracy_report.py.

The plots are accuracy_plots.py, the stiff-lighting and float32 sections accuracy_docs_stiff.py,
the light split section accuracy_split_docs.py.
Only the report command uses this (matplotlib is a development dependency, never the add-on's).
"""

import math
import os

import numpy as np
from accuracy_plots import plots


def pct(x, digits=1):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return f"{100 * x:.{digits}f}"


def _rows(res, **match):
    return [b for b in res["bakes"] if all(b[k] == v for k, v in match.items())]


def _first_reaching(rows, key, target):
    """(seconds, samples) of the cheapest row from which on every larger sample count is <= target."""
    rows = sorted(rows, key=lambda r: r["samples"])
    for i, r in enumerate(rows):
        if all(key(q) <= target for q in rows[i:]):
            return r["seconds"], r["samples"]
    return None


# --- markdown ------------------------------------------------------------------------------------


def table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


def recommendation(results):
    """Cheapest Fibonacci (order, samples) reaching each total-error target, per scene and HDRI."""
    cfg = results["config"]
    targets = [0.10, 0.05, 0.03, 0.02]
    rows = []
    for scene, res in results["scenes"].items():
        for h in cfg["hdris"]:
            cells = [scene, h]
            for t in targets:
                best = None
                for n in cfg["orders"]:
                    hit = _first_reaching(_rows(res, set="FIBONACCI", order=n), lambda r: r["total"][h], t)
                    if hit and (best is None or hit[0] < best[0]):
                        best = (hit[0], hit[1], n)
                cells.append("not reached" if best is None else f"order {best[2]}, {best[1]} ({best[0]:.2f} s)")
            rows.append(cells)
    return targets, rows


def saturation(results):
    """Per order: smallest sample count whose MC error is <= 1/3 of the band-limit error, for
    every scene and HDRI (beyond it, more rays hardly change the total error)."""
    cfg = results["config"]
    out = {}
    for n in cfg["orders"]:
        need = 0
        for scene, res in results["scenes"].items():
            for h in cfg["hdris"]:
                band = res["band_limit"][h][str(n)]
                hit = _first_reaching(_rows(res, set="FIBONACCI", order=n), lambda r: r["mc"][h], band / 3)
                need = max(need, hit[1] if hit else math.inf)
        out[n] = need
    return out


def write(results, docs_dir):
    img_dir = os.path.join(docs_dir, "images")
    os.makedirs(img_dir, exist_ok=True)
    images = plots(results, img_dir)
    cfg = results["config"]
    scenes = results["scenes"]
    L = []
    a = L.append
    a("# Accuracy: error against run time, stiff lighting, float32 storage\n")
    a(
        "Every number on this page is measured by one command (about "
        f"{results.get('wall_seconds', 0) / 60:.0f} min on the project's shared 2-core VM):\n"
    )
    a(
        "```sh\n.venv/bin/python benchmarks/accuracy_report.py          # writes this page, its plots and\n"
        "                                                        # benchmarks/accuracy_results.json\n"
        ".venv/bin/python benchmarks/accuracy_report.py --quick  # smoke run (~1 min, fewer settings)\n"
        ".venv/bin/python benchmarks/accuracy_report.py --from-json benchmarks/accuracy_results.json\n"
        "                                                        # rewrite the page from saved numbers\n```\n"
    )
    a(
        "It needs the development venv (bpy, embreex, matplotlib from `requirements-dev.txt`); the add-on "
        "itself does not use matplotlib. Extreme inputs (degenerate meshes, NaN, 1x1 images, ...) are "
        "covered by tests, listed in [extreme.md](extreme.md).\n"
    )
    a(
        f"Run: {results.get('started', '?')} to {results.get('finished', '?')}. Timings are wall-clock "
        "seconds on a noisy shared machine (other processes were running): read them as +-20 %.\n"
    )
    a("## Method\n")
    vs = ", ".join(
        f"**{s}** ({sum(r['vertices'])} vertices: object {r['vertices'][0]}, ground {r['vertices'][1]})"
        for s, r in scenes.items()
    )
    a(
        f"- Scenes: {vs}. `suzanne` is Suzanne subdivided once, smooth, standing on a 4 x 4 ground grid "
        "(32 x 32 quads); `torus` is a smooth torus (R 1, r 0.4, 48 x 24) tilted 50 degrees, on the same "
        "ground. All object transforms are the identity. Every vertex is a sample (objects and ground)."
    )
    a(
        f"- Lighting: Blender's bundled HDRIs {', '.join(cfg['hdris'])} (peaks below), projected by "
        "`api.project_world` at each order with `split_lights=False`: these sections measure the SH alone "
        "(the light split has its own section)."
    )
    a(
        "- Error = **relative RMSE of luminance** over all vertices: sqrt(mean (Y - Y_ref)^2) / "
        "sqrt(mean Y_ref^2), Y = 0.2126 R + 0.7152 G + 0.0722 B, with the PRT radiance clamped at 0 as the "
        "display does. The PRT radiance is what `api.shade` returns (checked in the run: max difference "
        f"{max(r['shade_check'] for r in scenes.values()):.1e} of the peak)."
    )
    a(
        f"- **Monte-Carlo (MC) error**: against a converged bake of the same order ({cfg['converged']} "
        "Fibonacci directions). **Total error**: against Cycles' `DIFFUSE` bake with "
        f"`pass_filter={{'DIRECT'}}` at {cfg['cycles_ref']} samples (E / pi, the same quantity), so it "
        "includes the SH band limit and the Cycles reference's own noise (estimated below)."
    )
    a(
        f"- Bakes: `api.bake` of both objects, orders {cfg['orders']}, samples {cfg['samples']}, direction "
        f"sets {', '.join(s.lower() for s in cfg['sets'])}; time = wall-clock of the whole `api.bake` call "
        "(2 threads, Embree)."
    )
    a(
        f"- Cycles: the same scene baked at {cfg['cycles_curve']} samples (different seeds from the "
        "reference), timed around `bpy.ops.object.bake` (CPU, 2 cores).\n"
    )
    a("HDRI peaks (max pixel value) and mean luminance:\n")
    a(
        table(
            ["HDRI", "peak", "mean Y"],
            [[h, f"{p['peak']:.3g}", f"{p['mean']:.3g}"] for h, p in results["hdri_peaks"].items()],
        )
        + "\n"
    )

    # Recommendation first.
    targets, rec_rows = recommendation(results)
    sat = saturation(results)
    a("## Which order and sample count to choose\n")
    a(
        "Cheapest Fibonacci setting (order, samples, bake seconds for the whole scene) whose **total** "
        "error against Cycles is at most the target at that sample count and every larger one:\n"
    )
    a(table(["scene", "HDRI"] + [f"<= {pct(t, 0)} %" for t in targets], rec_rows) + "\n")
    a(
        "Samples beyond which more rays hardly help (MC error at most one third of the band-limit error "
        "for every scene and HDRI): "
        + ", ".join(f"order {n}: {'>' + str(max(cfg['samples'])) if s == math.inf else s}" for n, s in sat.items())
        + ".\n"
    )
    a("RECOMMENDATION_TEXT\n")
    a("SPLIT_SECTION\n")  # accuracy_split_docs.section, once the hand-written notes are read

    # Cycles.
    a("## Cycles, the comparison curve\n")
    rows = []
    for s, res in scenes.items():
        for h in cfg["hdris"]:
            c = res["cycles"][h]
            rows.append(
                [s, h, f"{c['ref_seconds']:.1f}"] + [f"{x['seconds']:.1f} s, {pct(x['error'])} %" for x in c["curve"]]
            )
    a(
        table(
            ["scene", "HDRI", f"reference {cfg['cycles_ref']} samples, s"]
            + [f"{n} samples" for n in cfg["cycles_curve"]],
            rows,
        )
        + "\n"
    )
    a(
        "Cycles' error falls as samples^-1/2 from a fixed overhead of a few seconds (scene sync, "
        "kernel set-up). Its noise at the reference sample count, extrapolated from the "
        f"{cfg['cycles_curve'][-1]}-sample point (its error e is the noise of both bakes, e^2 = s^2 "
        f"({cfg['cycles_ref']} / {cfg['cycles_curve'][-1]} + 1) with s the reference's), is "
        + ", ".join(
            f"{pct(res['cycles'][h]['curve'][-1]['error'] / math.sqrt(cfg['cycles_ref'] / cfg['cycles_curve'][-1] + 1))} %"
            f" ({sc} / {h})"
            for sc, res in scenes.items()
            for h in cfg["hdris"]
        )
        + ": a floor under every total error below.\n"
    )

    # Band limit.
    a("## SH band limit (converged transfer against Cycles)\n")
    rows = [
        [s, h] + [pct(res["band_limit"][h][str(n)]) for n in cfg["orders"]]
        for s, res in scenes.items()
        for h in cfg["hdris"]
    ]
    a(table(["scene", "HDRI"] + [f"order {n}, %" for n in cfg["orders"]], rows) + "\n")

    # Bake times.
    a("## Bake time (Fibonacci, whole `api.bake` call, seconds)\n")
    for s, res in scenes.items():
        rows = [
            [f"order {n}"]
            + [
                f"{next(r['seconds'] for r in _rows(res, set='FIBONACCI', order=n, samples=k)):.2f}"
                for k in cfg["samples"]
            ]
            for n in cfg["orders"]
        ]
        a(
            f"{s} ({sum(res['vertices'])} vertices; converged bake of {cfg['converged']} directions: "
            f"{res['converged']['seconds']:.1f} s):\n"
        )
        a(table(["", *[str(k) for k in cfg["samples"]]], rows) + "\n")
    a("Time is nearly independent of the order: it is ray tracing.\n")

    # Error tables.
    a("## Error against samples (Fibonacci): MC error / total error, %\n")
    for img in images[:-1]:
        a(f"![error against seconds]({'images/' + img})\n")
    for s, res in scenes.items():
        for h in cfg["hdris"]:
            rows = []
            for n in cfg["orders"]:
                cells = [f"order {n}"]
                for k in cfg["samples"]:
                    r = _rows(res, set="FIBONACCI", order=n, samples=k)[0]
                    cells.append(f"{pct(r['mc'][h], 2)} / {pct(r['total'][h])}")
                rows.append(cells)
            a(f"**{s} / {h}**\n")
            a(table(["", *[str(k) for k in cfg["samples"]]], rows) + "\n")

    # Direction sets.
    a("## Direction sets: which reaches a given error in the least time\n")
    a(
        "Transfer MC error = RMS over vertices of |t - t_conv| (L2 over the coefficients) / RMS |t_conv|, "
        "independent of the lighting.\n"
    )
    a(f"![direction sets](images/{images[-1]})\n")
    rows = []
    for s, res in scenes.items():
        for n in cfg["orders"]:
            for t in (0.10, 0.05, 0.02, 0.01):
                cells = [s, n, f"{pct(t, 0)} %"]
                for kind in cfg["sets"]:
                    hit = _first_reaching(_rows(res, set=kind, order=n), lambda r: r["transfer_rel_error"], t)
                    cells.append("not reached" if hit is None else f"{hit[0]:.2f} s ({hit[1]})")
                rows.append(cells)
    a("Seconds (samples) to reach a transfer MC error, at that sample count and every larger one:\n")
    a(table(["scene", "order", "target"] + [k.lower() for k in cfg["sets"]], rows) + "\n")
    a("SETS_TEXT\n")

    # Error estimate.
    a("## The bake's error estimate against the measured error\n")
    a(
        "`report.error_estimate` (RMS over vertices of the per-point estimate, see [bake.md](bake.md)) divided "
        "by the measured RMS |t - t_conv| of the same bake; in brackets the ratio before the Fibonacci "
        "calibration (`core.transfer.quadrature.error_calibration`):\n"
    )
    for kind in cfg["sets"]:
        ratios = [
            b["estimate"] / b["true_transfer_error"]
            for res in scenes.values()
            for b in res["bakes"]
            if b["set"] == kind
        ]
        a(
            f"- {kind.lower()}: {min(ratios):.2f} to {max(ratios):.2f} (median {np.median(ratios):.2f}) over "
            "every scene, order and sample count"
        )
    a("")
    for kind in cfg["sets"]:
        rows = []
        for s, res in scenes.items():
            for n in cfg["orders"]:
                cells = [s, n]
                for k in cfg["samples"]:
                    r = _rows(res, set=kind, order=n, samples=k)[0]
                    raw = r["estimate"] / r.get("calibration", 1.0) / r["true_transfer_error"]
                    cells.append(
                        f"{r['estimate'] / r['true_transfer_error']:.2f}"
                        + (f" ({raw:.2f})" if r.get("calibration", 1.0) != 1.0 else "")
                    )
                rows.append(cells)
        a(f"**{kind.lower()}**\n")
        a(table(["scene", "order", *[str(k) for k in cfg["samples"]]], rows) + "\n")
    a("ESTIMATE_TEXT\n")

    import accuracy_docs_stiff  # (imports pct and table from here)

    accuracy_docs_stiff.stiff_and_float32(a, results)
    text = "\n".join(L)
    extra = os.path.join(os.path.dirname(os.path.abspath(__file__)), "accuracy_text.md")
    notes = {}
    if os.path.isfile(extra):  # hand-written conclusions, keyed by the placeholders above
        key = None
        for line in open(extra).read().splitlines():
            if line.startswith("@@ "):
                key = line[3:].strip()
                notes[key] = []
            elif key:
                notes[key].append(line)
    import accuracy_split_docs

    text = text.replace("SPLIT_SECTION\n", accuracy_split_docs.section(results, "\n".join(notes.get("SPLIT_TEXT", []))))
    for key in ("RECOMMENDATION_TEXT", "SETS_TEXT", "ESTIMATE_TEXT", "WINDOW_TEXT", "FLOAT32_TEXT"):
        text = text.replace(key + "\n", "\n".join(notes.get(key, [])).strip() + "\n")
    with open(os.path.join(docs_dir, "accuracy.md"), "w") as fh:
        fh.write(text)
    print("wrote", os.path.join(docs_dir, "accuracy.md"), images)
