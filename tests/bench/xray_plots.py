"""The X-ray methods' plots on docs/benchmarks.md (time against error, speed-up over magnification), and the
names and styles the page's X-ray tables share with them."""

from __future__ import annotations

import math
from pathlib import Path

# The aims the page judges the X-ray methods by.
GOALS = {"speedup_m4": 6.0, "speedup_m8": 20.0, "rel_rmse_pct": 1.0, "pcvr_mvox": 200.0}

METHOD_ORDER = ["regular", "pcvr_bilinear", "pcvr_gauss", "bilinear_spread"]
LABELS = {"regular": "regular", "pcvr_bilinear": "pcvr + bilinear", "pcvr_gauss": "pcvr + gauss1.4",
          "bilinear_spread": "bilinear spread"}
STYLE = {"regular": ("tab:gray", "o"), "pcvr_bilinear": ("tab:blue", "s"), "pcvr_gauss": ("tab:purple", "D"),
         "bilinear_spread": ("tab:orange", "^")}


def vol_name(v: dict) -> str:
    return f"{v['kind']} {v['n']}³"


def main_volume(results: dict):
    """The largest dense volume: where the goals are judged."""
    dense = [v for v in results["volumes"] if v["kind"] == "dense"] or results["volumes"]
    return max(dense, key=lambda v: v["n"]) if dense else None


def plain_log_ticks(ax) -> None:
    """Log axes labelled 1, 2, 5, 10, ... instead of 2x10^0."""
    from matplotlib.ticker import FuncFormatter, LogLocator

    def label(x, _pos):
        return f"{x:g}" if x >= 0.01 else f"{x:.0e}"

    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
        axis.set_major_formatter(FuncFormatter(label))
        axis.set_minor_formatter(FuncFormatter(lambda x, p: ""))


def plot_time_vs_error(results: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    vols = results["volumes"]
    cols = 2
    rows = max(1, math.ceil(len(vols) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(6.2 * cols, 4.6 * rows), squeeze=False)
    for ax, v in zip(axes.flat, vols):
        for key in METHOD_ORDER:
            pts = []
            for mag, cfg in sorted(v["configs"].items(), key=lambda kv: int(kv[0])):
                m = cfg["methods"].get(key)
                if m:
                    pts.append((1e3 * m["median_s"], 100 * m["rel_rmse"], int(mag)))
            if not pts:
                continue
            color, marker = STYLE[key]
            ax.plot([p[0] for p in pts], [p[1] for p in pts], color=color, marker=marker, label=LABELS[key], lw=1.4, ms=6)
            for x, y, mag in pts:
                ax.annotate(f"{mag}", (x, y), textcoords="offset points", xytext=(5, 4), fontsize=8, color=color)
        ax.set_xscale("log")
        ax.set_yscale("log")
        plain_log_ticks(ax)
        ax.set_xlabel("median render time (ms, log)")
        ax.set_ylabel("relative RMSE vs exact (%, log)")
        ax.set_title(f"{vol_name(v)} ({v['active_voxels'] / 1e6:.2g} M active voxels)")
        ax.axhline(GOALS["rel_rmse_pct"], color="tab:red", lw=0.8, ls="--")
        ax.grid(True, which="both", alpha=0.3)
    for ax in list(axes.flat)[len(vols):]:
        ax.axis("off")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.suptitle("Time versus error (numbers at the points: magnification; dashed: 1% goal)", y=0.995, fontsize=12)
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.965), ncol=4, frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_speedup(results: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    vols = results["volumes"]
    fig, axes = plt.subplots(1, len(vols), figsize=(3.6 * len(vols), 3.8), squeeze=False, sharey=True)
    main = main_volume(results)
    for ax, v in zip(axes.flat, vols):
        for key in METHOD_ORDER[1:]:
            mags, ups = [], []
            for mag, cfg in sorted(v["configs"].items(), key=lambda kv: int(kv[0])):
                if key in cfg["methods"]:
                    mags.append(int(mag))
                    ups.append(cfg["methods"][key]["speedup"])
            color, marker = STYLE[key]
            ax.plot(mags, ups, color=color, marker=marker, label=LABELS[key])
        if v is main:
            goals = [(m, GOALS[k]) for m, k in ((4, "speedup_m4"), (8, "speedup_m8")) if str(m) in v["configs"]]
            if goals:
                ax.plot([g[0] for g in goals], [g[1] for g in goals], "r*", ms=11, label="goal (pcvr)")
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xticks([int(k) for k in v["configs"]])
        ax.set_xticklabels([k for k in v["configs"]])
        ax.set_xlabel("magnification (pixels per voxel)")
        ax.set_title(vol_name(v), fontsize=10)
        ax.axhline(1.0, color="k", lw=0.6)
        ax.grid(True, which="both", alpha=0.3)
    axes.flat[0].set_ylabel("speed-up vs regular (same run)")
    from matplotlib.ticker import FuncFormatter
    axes.flat[0].yaxis.set_major_formatter(FuncFormatter(lambda y, _p: f"{y:g}"))
    handles, labels = [], []
    for ax in axes.flat:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.legend(handles, labels, loc="upper center", ncol=4, frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 0.88))
    fig.savefig(path, dpi=110)
    plt.close(fig)
