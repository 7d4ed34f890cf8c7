"""The "Light split" section of docs/accuracy.md from the numbers of benchmarks/accuracy_split.py."""

from accuracy_split import TARGET, UNCERTAINTY_FACTOR


def pct(x, digits=1):
    return "-" if x is None else f"{100 * x:.{digits}f}"


def verdict(error, target, uncertainty):
    """'yes' (error <= target), 'yes (ref.)' (error <= 1.25 x the reference's uncertainty), or 'no'."""
    if error <= target:
        return "yes"
    if error <= UNCERTAINTY_FACTOR * uncertainty:
        return "yes (ref.)"
    return "**no**"


def table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


def summary(split):
    """(met, total, list of misses) over every scene, HDRI and order with the split."""
    met, total, misses = 0, 0, []
    for scene, res in split["scenes"].items():
        for hdri, row in res["rows"].items():
            for n in split["orders"]:
                total += 1
                v = verdict(row["prt"][f"{n}s"]["cycles"], TARGET[n], row["cycles_vs_brute"])
                if v.startswith("yes"):
                    met += 1
                else:
                    misses.append(f"{scene} / {hdri} order {n} ({pct(row['prt'][f'{n}s']['cycles'])} %)")
    return met, total, misses


def rule_table(split):
    """Markdown of the rule sweep (rows "rule" of every HDRI), or "" when it was not measured."""
    from prt_addon.core.lights import extraction as core_lights

    cells = {}
    for scene, res in split["scenes"].items():
        for hdri, row in res["rows"].items():
            for r in row.get("rule", []):
                key = (r["mean_factor"], r["compact_fraction"])
                cells.setdefault(key, []).append((scene, hdri, r))
    rows = []
    for (m, c), found in cells.items():
        met = sum(r[str(n)] <= TARGET[n] for _, _, r in found for n in split["orders"])
        worst = [max(r[str(n)] for _, _, r in found) for n in split["orders"]]
        court = {scene: r for scene, hdri, r in found if hdri == "courtyard"}
        product = m == core_lights.MEAN_FACTOR and c == core_lights.COMPACT_FRACTION
        label = f"{m:g}, {100 * c:g} %" + (" (**the rule**)" if product else "")
        court_cells = [" / ".join(pct(r[str(n)]) for r in court.values()) for n in split["orders"]]
        t = " / ".join(f"{r['value']:.2f}" for r in list(court.values())[:1])
        rows.append([label, f"{met} of {len(found) * len(split['orders'])}", *map(pct, worst), t, *court_cells])
    if not rows:
        return ""
    header = ["m, c", "targets met"] + [f"worst o{n}, %" for n in split["orders"]] + ["courtyard T"]
    header += [f"courtyard o{n} (" + " / ".join(split["scenes"]) + "), %" for n in split["orders"]]
    return table(header, rows)


def section(results, text):
    """Markdown of the section; `text` is the hand-written conclusion (accuracy_text.md)."""
    split = results.get("split")
    if not split:
        return ""
    L = ["## Light split: every bundled HDRI, with and without the split\n"]
    a = L.append
    a(
        "The same scenes, baked once at order 8 with "
        f"{split['prt_samples']} Fibonacci directions; `api.shade` at orders 4 and 8 (order 4: the first "
        "16 coefficients of the same transfer), after `api.project_world(split_lights=False)` and "
        "`split_lights=True` (automatic threshold, at most 4 lights, each shaded by 16 power-weighted "
        "samples of its own texels, one ray each: [lights.md](lights.md)). Error: relative RMSE of luminance over all vertices, as above. "
        "`accuracy_report.py --only-split` measures this section alone; the Cycles and brute-force "
        "references are cached in `benchmarks/accuracy_references.json` and reused while the scenes "
        "and settings match.\n"
    )
    a(
        f"- **Cycles**: `DIFFUSE` bake, `pass_filter={{'DIRECT'}}`, {split['cycles_samples']} samples, the "
        "Environment Texture at Blender's default (linear) interpolation."
    )
    a(
        "- **Brute force**: an independent quadrature of the HDRI's texels per vertex, "
        "sum_k L_k Omega_k max(0, n . d_k) V_k / pi: the "
        f"{split['bright']} texels with the most power (luminance x solid angle) one by one at full resolution "
        f"(1024 x 512), every other texel summed into blocks of a {split['coarse'][1]} x {split['coarse'][0]} "
        "grid (power kept, node at the block's power-weighted direction); exact texel solid angles; "
        "V traced with Embree from the bake's own ray origins (offset along the normal and into the "
        "point's own surface). Its own quadrature error is bounded by comparing it with a "
        f"{split['coarse_check'][1]} x {split['coarse_check'][0]} grid (column *BF grid*)."
    )
    a(
        "- **Uncertainty of the reference** u = Cycles against the brute force. Target: with the split, "
        f"order 8 at most {pct(TARGET[8])} % and order 4 at most {pct(TARGET[4], 0)} % from Cycles, or, "
        f"where u is larger, at most {UNCERTAINTY_FACTOR} u (*yes (ref.)*).\n"
    )
    pics = split.get("pictures")
    if pics:
        f = pics["files"]
        a(
            f"**{pics['scene']} / {pics['hdri']}, order {pics['order']}**, seen from a camera (AgX, exposure "
            f"{pics['exposure']:+.2f}): Cycles' per-vertex bake, PRT without the split and PRT with it "
            "(per-vertex `api.shade` values, the quantity the table measures, all three Gouraud-interpolated "
            "by the same rasteriser: the `gpu` module's builtin `SMOOTH_COLOR` shader), and PRT with the "
            "split as the viewport draws it (`api.render_view`: the sun per pixel with its shadow map).\n"
        )
        a("| Cycles (vertex bake) | PRT, no split | PRT, split | PRT, split, viewport shader |")
        a("|---|---|---|---|")
        a(
            "| "
            + " | ".join(f"![{k}](images/{f[k]})" for k in ("cycles", "prt", "prt_split", "prt_split_view"))
            + " |\n"
        )
    for scene, res in split["scenes"].items():
        rows = []
        for hdri, row in res["rows"].items():
            lt = row["lights"]
            lights = (
                "-" if not lt["count"] else f"{lt['count']}, {pct(lt['share'], 0)} %, {lt['elevation_deg']:.0f} deg"
            )
            u = row["cycles_vs_brute"]
            cells = [hdri, lights, pct(u, 2), pct(row["brute_vs_check"], 2)]
            for n in split["orders"]:
                p = row["prt"]
                cells += [
                    pct(p[str(n)]["cycles"]),
                    f"**{pct(p[f'{n}s']['cycles'])}**",
                    pct(p[f"{n}s"]["brute"]),
                    verdict(p[f"{n}s"]["cycles"], TARGET[n], u),
                ]
            rows.append(cells)
        header = ["HDRI", "lights (count, share, elevation)", "u: Cycles vs BF, %", "BF grid, %"]
        for n in split["orders"]:
            header += [f"o{n} no split, %", f"o{n} split, %", f"o{n} split vs BF, %", f"o{n} met"]
        a(f"**{scene}** ({sum(res['vertices'])} vertices), error against Cycles unless said:\n")
        a(table(header, rows) + "\n")
    for scene, res in split["scenes"].items():
        for hdri, row in res["rows"].items():
            if not row.get("sweep"):
                continue
            cells = []
            for r in row["sweep"]:
                t = "automatic" if r["threshold"] == 0 else f"{r['threshold']:g}"
                wide = f"{max(r['angles_deg']):.0f}" if r["angles_deg"] else "-"
                errors = []
                for n in split["orders"]:
                    e = r[str(n)]
                    errors += [f"{pct(e['cycles'])} / {pct(e['brute'])}", pct(e["discs"]["cycles"])]
                cells.append([t, r["max_lights"], r["count"], pct(r["share"], 0), wide, *errors])
            a(
                f"**{scene} / {hdri}: other thresholds and light counts** (error against Cycles / against the "
                "brute force, %, with the lights' samples; *discs*: the same lights shaded as uniform discs "
                "of their moment radius, against Cycles; widest light's radius in degrees):\n"
            )
            header = ["threshold", "max lights", "lights", "share, %", "widest, deg"]
            for n in split["orders"]:
                header += [f"order {n}", f"o{n} discs"]
            a(table(header, cells) + "\n")
            if row.get("parts"):
                cells = []
                for r in row["parts"]:
                    t = {0.0: "automatic", "old": "old rule (8 mean, 1 %)"}.get(r["threshold"])
                    t = t or f"{r['threshold']:g}"
                    wide = f"{max(r['angles_deg']):.0f}" if r["angles_deg"] else "-"
                    sky = [pct(r["sky"][str(n)], 2) for n in split["orders"]]
                    cells.append([t, f"{r['value']:.2f}", r["lights"], wide, *sky])
                    cells[-1] += [pct(r["lights_samples"], 2), pct(r["lights_discs"], 2)]
                a(
                    f"**{scene} / {hdri}: the error by part** (each part of `api.shade` against the brute force "
                    "of that part alone: the SH of the residual sky against the quadrature of the residual "
                    "image, the lights against the quadrature of their excess texels one by one; RMS over "
                    "the vertices / RMS of the whole image's brute force, %):\n"
                )
                header = ["threshold", "T", "lights", "widest, deg"]
                header += [f"sky, order {n}" for n in split["orders"]] + ["lights, samples", "lights, discs"]
                a(table(header, cells) + "\n")
    rule = rule_table(split)
    if rule:
        a(
            "**Other constants of the threshold rule** T = max(m x mean, T_compact(c)) (c: the share of the "
            "sphere the bright texels may cover), every scene and HDRI, 4 lights, error against Cycles; "
            "the product's rule is marked:\n"
        )
        a(rule + "\n")
    met, total, misses = summary(split)
    a(
        f"Targets met: **{met} of {total}** (scene x HDRI x order)"
        + (": missed " + "; ".join(misses) if misses else "")
        + ".\n"
    )
    times = [r["cycles_seconds"] for s in split["scenes"].values() for r in s["rows"].values()]
    brute = [r["brute_seconds"] for s in split["scenes"].values() for r in s["rows"].values()]
    shade = [r["prt"]["8s"]["shade_seconds"] for s in split["scenes"].values() for r in s["rows"].values()]
    a(
        f"Cost per scene and HDRI: Cycles {min(times):.0f} to {max(times):.0f} s, brute force {min(brute):.0f} to "
        f"{max(brute):.0f} s, `api.shade` with the split (16 rays per light and vertex) {min(shade):.2f} to "
        f"{max(shade):.2f} s for the whole scene.\n"
    )
    a(text.strip() + "\n")
    return "\n".join(L)
