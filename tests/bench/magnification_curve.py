#!/usr/bin/env python3
"""PCVR's X-ray time over magnification: is a non-whole magnification, or a perspective camera, as fast as a
whole-number orthographic one?

For each data set (the Gaussian blobs of datasets.py, and its CT head phantom with every second slice, so with
voxels of 1:1:2 as CT scans often have) and each magnification m from 1
to 8, the oblique orthographic view of views.py at m pixels per voxel and the perspective view with m pixels
per voxel at the volume's centre are rendered with `method="pcvr"` (automatic stride, bilinear post filter) on
one thread; the calling thread's CPU time of one render is the median of REPS (the machine is shared: CPU time on one thread is
what other work disturbs least). Throughput is active voxels per CPU second.

    python tests/bench/magnification_curve.py [--quick]     # prints the table
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import datasets  # noqa: E402
from timing import cpu_seconds  # noqa: E402
import views  # noqa: E402

DATASETS = ("blobs", "ct")
NAMES = {"blobs": "Gaussian blobs", "ct": "CT head phantom, 1:1:2 voxels"}
SIZE = 128
MAGNIFICATIONS = [1.0 + 0.25 * i for i in range(29)]  # 1 to 8
REPS = 3
# The magnifications whose rows the page's table shows (all are in the plot data).
TABLE_MAGNIFICATIONS = (1.0, 1.5, 2.0, 2.25, 2.5, 3.0, 3.5, 4.0, 5.5, 8.0)


def volume(key: str, size: int):
    """(values, index_to_world) of a data set; the CT phantom keeps every second slice along k."""
    phantom = datasets.BY_KEY[key].make(size)
    if key != "ct":
        return phantom.values, phantom.index_to_world
    xf = np.array(phantom.index_to_world, dtype=np.float64)
    xf[:3, 2] *= 2.0
    return np.ascontiguousarray(phantom.values[:, :, ::2]), xf


def run(quick: bool, log) -> dict:
    import pcvr_native as pn
    size = 64 if quick else SIZE
    mags = MAGNIFICATIONS[::4] if quick else MAGNIFICATIONS
    reps = 1 if quick else REPS
    out = {"size": size, "reps": reps, "threads": 1, "datasets": {}}
    for key in DATASETS:
        values, xf = volume(key, size)
        grid = pn.Grid.from_dense(values, xf)
        active = int(grid.active_voxel_count)
        rows = []
        for m in mags:
            for projection in ("ortho", "persp"):
                make = views.oblique if projection == "ortho" else views.perspective
                view = make(values.shape, xf, m)
                cam = views.camera(view)
                stats = {}
                pn.render_xray(grid, cam, "pcvr", threads=1, stats=stats)
                seconds = cpu_seconds(lambda: pn.render_xray(grid, cam, "pcvr", threads=1), reps)
                rows.append({"magnification": m, "projection": projection, "width": cam.width, "height": cam.height,
                             "cpu_s": seconds, "mvoxels_per_s": active / seconds / 1e6,
                             "strides": list(stats["strides"]), "taps_per_voxel": stats.get("taps", 0) / max(1, stats["voxels"])})
            log(f"  {key} m={m:g}: ortho {1e3 * rows[-2]['cpu_s']:.1f} ms, perspective {1e3 * rows[-1]['cpu_s']:.1f} ms")
        out["datasets"][key] = {"name": NAMES[key], "active_voxels": active, "rows": rows}
    return out


def ratios(rows) -> dict:
    """Slowest over fastest magnification per projection, and perspective over orthographic (median over m)."""
    by = {p: {r["magnification"]: r["cpu_s"] for r in rows if r["projection"] == p} for p in ("ortho", "persp")}
    spread = {p: max(t.values()) / min(t.values()) for p, t in by.items()}
    persp_over_ortho = [by["persp"][m] / by["ortho"][m] for m in by["ortho"] if m in by["persp"]]
    return {"ortho_spread": spread["ortho"], "persp_spread": spread["persp"],
            "persp_over_ortho": statistics.median(persp_over_ortho), "persp_over_ortho_max": max(persp_over_ortho)}


def _strides(strides) -> str:
    return ", ".join(f"{s:.2f}".rstrip("0").rstrip(".") for s in strides)


def section(results) -> list[str]:
    """The benchmark page's section (markdown lines)."""
    if not results:
        return []
    lines = ["## X-ray speed over magnification", "",
             f"`pcvr` (automatic stride, bilinear post filter) on {results['size']}^3 volumes through the oblique "
             "orthographic view at m pixels per voxel and the perspective view with m pixels per voxel at the "
             f"volume's centre (`tests/bench/magnification_curve.py`); CPU time of one render on one thread, median "
             f"of {results['reps']} (the calling thread's CPU time: see tests/bench/timing.py). The automatic stride puts "
             "a subgrid node every projected voxel spacing, so every orthographic footprint is PCVR's 4 x 4 window "
             "whatever m; perspective views split into depth bands 2^(1/4) apart, and each block's footprints come "
             "from its projection linearised (docs/how-it-works.md, *Perspective: depth bands*).", ""]
    for key, entry in results["datasets"].items():
        r = ratios(entry["rows"])
        lines += [f"**{entry['name']}** ({entry['active_voxels']:,} active voxels): slowest over fastest magnification "
                  f"{r['ortho_spread']:.2f}x orthographic, {r['persp_spread']:.2f}x perspective; perspective over "
                  f"orthographic {r['persp_over_ortho']:.1f}x (median over m, at most {r['persp_over_ortho_max']:.1f}x).", "",
                  "| m | orthographic image | ms | Mvoxels/s | stride | perspective image | ms | Mvoxels/s | strides |",
                  "|---|---|---|---|---|---|---|---|---|"]
        by = {(row["magnification"], row["projection"]): row for row in entry["rows"]}
        for m in sorted({row["magnification"] for row in entry["rows"]}):
            if m not in TABLE_MAGNIFICATIONS and len(entry["rows"]) > 2 * len(TABLE_MAGNIFICATIONS):
                continue
            o, p = by[(m, "ortho")], by[(m, "persp")]
            lines.append(f"| {m:g} | {o['width']} x {o['height']} | {1e3 * o['cpu_s']:.1f} | {o['mvoxels_per_s']:.0f} | "
                         f"{_strides(o['strides'])} | {p['width']} x {p['height']} | {1e3 * p['cpu_s']:.1f} | "
                         f"{p['mvoxels_per_s']:.0f} | {_strides(p['strides'])} |")
        lines.append("")
    return lines


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true", help="64^3, magnifications 1 to 8 in steps of 1, one repetition")
    args = p.parse_args(argv)
    results = run(args.quick, lambda msg: print(msg, file=sys.stderr, flush=True))
    print("\n".join(section(results)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
