"""The stiff-lighting (ringing and windows) and float32 sections of docs/accuracy.md."""

import numpy as np
from accuracy_docs import pct, table
from accuracy_report import WINDOWS  # the windows the report measures


def stiff_and_float32(a, results):
    """Append the two sections' lines with a (list.append), placeholders WINDOW_TEXT, FLOAT32_TEXT."""
    cfg = results["config"]
    scenes = results["scenes"]
    # Stiff.
    a("## Stiff lighting: ringing and windows\n")
    a(
        "Shaded radiance sum_i L_i t_i with the **converged** transfer (so only the lighting's band limit and "
        "the window matter), lighting windowed by each window of `benchmarks/windows/`: `HANNING` and `LANCZOS` at "
        "their default width (the order), `AUTO_LAPLACIAN` and `AUTO_HANNING` the weakest window making the "
        "lighting non-negative on the sphere (`auto_window`). Columns: fraction of vertices with a negative "
        "channel before clamping, the minimum radiance over vertices and channels divided by the mean truth "
        "luminance, and the total error of the clamped luminance (the display clamps at 0). Truth: Cycles "
        f"({cfg['cycles_ref']} samples) for the HDRIs; for the synthetic caps (a sun disk of angular radius "
        "0.5 to 5 degrees and radiance 1e4 to 1e6 on a uniform background of 1, 35 degrees above the "
        "horizon) the cap is traced exactly (400 rays per vertex into the cap) and the background is the "
        "converged t_0. HDRIs without a Cycles truth show ringing only.\n"
    )
    # Summary over all cases and orders, per window.
    rows = []
    for w in WINDOWS:
        neg, mins, ratio, finite = [], [], [], True
        for s, res in scenes.items():
            by = {(r["case"], r["order"], r["window"]): r for r in res["stiff"]}
            for (case, n, ww), r in by.items():
                if ww != w:
                    continue
                neg.append(r["neg_fraction"])
                mins.append(r["min_rel"])
                finite &= r["finite"]
                if "err_clamped" in r:
                    ratio.append(r["err_clamped"] / by[(case, n, "NONE")]["err_clamped"])
        rows.append(
            [
                w,
                f"{pct(max(neg), 2)}",
                f"{100 * min(mins):.2f} %",
                f"{np.median(ratio):.2f}",
                f"{min(ratio):.2f} - {max(ratio):.2f}",
                "yes" if finite else "NO",
            ]
        )
    gain = [
        (r["err_clamped"] - r["err_unclamped"]) / r["err_unclamped"]
        for res in scenes.values()
        for r in res["stiff"]
        if r["window"] == "NONE" and "err_clamped" in r
    ]
    a(
        f"Clamping at 0 (no window) changes the error by {100 * min(gain):+.1f} % to {100 * max(gain):+.1f} % "
        "(relative) against the unclamped radiance: it never makes it worse, since the truth is >= 0.\n"
    )
    a("Summary over every case, order and scene:\n")
    a(
        table(
            [
                "window",
                "max negative fraction, %",
                "lowest min / mean",
                "median error ratio to NONE",
                "error ratio range",
                "all finite",
            ],
            rows,
        )
        + "\n"
    )
    s0 = next(iter(scenes))
    for n in [n for n in (4, 8) if n in cfg["orders"]]:
        rows = []
        cases = []
        for r in scenes[s0]["stiff"]:
            if r["case"] not in cases:
                cases.append(r["case"])
        for case in cases:
            cells = [case]
            for w in WINDOWS:
                r = next(r for r in scenes[s0]["stiff"] if r["case"] == case and r["order"] == n and r["window"] == w)
                err = f"{pct(r['err_clamped'])}" if "err_clamped" in r else "-"
                cells.append(f"{pct(r['neg_fraction'], 1)} / {100 * r['min_rel']:.1f} / {err}")
            rows.append(cells)
        a(f"**{s0}, order {n}**: negative vertices % / min over mean % / error %\n")
        a(table(["case", *WINDOWS], rows) + "\n")
    a("WINDOW_TEXT\n")

    # Float32.
    a("## Float32 storage\n")
    rows = []
    for s, res in scenes.items():
        f = res["float32"]
        worst = max(r["f32_error"] for r in f["rows"])
        mc = min(r["mc_error"] for r in f["rows"])
        rows.append(
            [
                s,
                f["samples"],
                f"{f['coeff_rel']:.1e}",
                f"{f['stored_vs_float64']:.1e}",
                f"{worst:.1e}",
                f"{mc:.1e}",
                f"{mc / worst:.0e}",
            ]
        )
    a(
        "The same bake computed in float64 (the sums are float64) and rounded to float32 (what the "
        "`FLOAT_COLOR` attributes hold), order " + str(max(cfg["orders"])) + ", Fibonacci:\n"
    )
    a(
        table(
            [
                "scene",
                "samples",
                "max coefficient rounding / max |t|",
                "stored bake vs float64 / max |t|",
                "worst shading error (any HDRI, order)",
                "smallest MC error at those samples",
                "ratio",
            ],
            rows,
        )
        + "\n"
    )
    a("FLOAT32_TEXT\n")
