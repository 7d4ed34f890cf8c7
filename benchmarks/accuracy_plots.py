"""Plots of docs/accuracy.md (error against seconds, direction sets) from the report's numbers.

Only the report command uses this (matplotlib is a development dependency, never the add-on's).
"""

import os

COLORS = {2: "tab:blue", 3: "tab:orange", 4: "tab:green", 6: "tab:red", 8: "tab:purple"}
SET_STYLE = {"FIBONACCI": "-o", "STRATIFIED": "-s", "UNIFORM": "-^"}


def _rows(res, **match):
    return [b for b in res["bakes"] if all(b[k] == v for k, v in match.items())]


def plots(results, img_dir):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cfg = results["config"]
    out = []
    for scene, res in results["scenes"].items():
        hdris = cfg["hdris"]
        fig, axes = plt.subplots(2, len(hdris), figsize=(4.2 * len(hdris), 7.5), squeeze=False)
        for j, h in enumerate(hdris):
            for row, key, title in ((0, "total", "total error vs Cycles"), (1, "mc", "Monte-Carlo error")):
                ax = axes[row, j]
                for n in cfg["orders"]:
                    rows = sorted(_rows(res, set="FIBONACCI", order=n), key=lambda r: r["samples"])
                    ax.loglog(
                        [r["seconds"] for r in rows],
                        [100 * r[key][h] for r in rows],
                        "-o",
                        color=COLORS.get(n),
                        ms=3,
                        label=f"PRT order {n}",
                    )
                if row == 0:
                    c = res["cycles"][h]["curve"]
                    ax.loglog([x["seconds"] for x in c], [100 * x["error"] for x in c], "k--s", ms=4, label="Cycles")
                    for x in c:
                        ax.annotate(str(x["samples"]), (x["seconds"], 100 * x["error"]), fontsize=7)
                ax.set_title(f"{scene} / {h}: {title}", fontsize=9)
                ax.set_xlabel("seconds")
                ax.set_ylabel("relative RMSE of luminance, %")
                ax.grid(True, which="both", alpha=0.3)
        axes[0, 0].legend(fontsize=7)
        fig.suptitle("Fibonacci directions, 64 to 4096 samples per order (points left to right)", fontsize=9)
        fig.tight_layout()
        name = f"accuracy_{scene}.png"
        fig.savefig(os.path.join(img_dir, name), dpi=90)
        plt.close(fig)
        out.append(name)
    # Direction sets.
    scenes = list(results["scenes"])
    orders = [n for n in (4, 8) if n in cfg["orders"]] or cfg["orders"][-1:]
    fig, axes = plt.subplots(len(orders), len(scenes), figsize=(4.5 * len(scenes), 3.8 * len(orders)), squeeze=False)
    for i, n in enumerate(orders):
        for j, scene in enumerate(scenes):
            ax = axes[i, j]
            for kind in cfg["sets"]:
                rows = sorted(_rows(results["scenes"][scene], set=kind, order=n), key=lambda r: r["samples"])
                ax.loglog(
                    [r["seconds"] for r in rows],
                    [100 * r["transfer_rel_error"] for r in rows],
                    SET_STYLE.get(kind, "-o"),
                    ms=3,
                    label=kind.lower(),
                )
            ax.set_title(f"{scene}, order {n}: transfer MC error", fontsize=9)
            ax.set_xlabel("bake seconds")
            ax.set_ylabel("RMS |t - t_conv| / RMS |t_conv|, %")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(img_dir, "accuracy_sets.png"), dpi=90)
    plt.close(fig)
    out.append("accuracy_sets.png")
    return out
