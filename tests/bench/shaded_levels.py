#!/usr/bin/env python3
"""Levels of detail in shaded rendering and MIP: image error and time per level and magnification.

For each volume (the CT phantom with a bone-like transfer function; Gaussian blobs with a translucent
one), orthographic views along an oblique direction at magnifications 1/2 to 1/64, render_shaded and
render_mip at levels 0 to 3 with the sheets one voxel of the level apart ("level voxels") and one voxel
of level 0 apart ("level-0 voxels"), against level 0, against level 0's pixel means (rendered at 4 x 4
times the pixels and box-averaged) and against method="raycast" at level 0 (steps of 0.1 voxel). Errors:
PSNR (dB, peak 1) and relative RMSE of premultiplied RGBA, and for MIP the relative RMSE of the maxima above the
background; time: CPU seconds of one thread (tests/bench/timing.py).

    python tests/bench/shaded_levels.py [--quick] [--no-raycast]     # prints the tables
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
# Appended, not put first: make bench imports this beside minification_bench, whose test module must find
# tests/native's conftest before tests/ (which also holds one).
sys.path.append(str(HERE))
sys.path.append(str(HERE.parent))

from level_scenes import TRANSLUCENT, pixel_means, scattered_blobs  # noqa: E402
from timing import cpu_seconds  # noqa: E402
from xray_helpers import frame_ortho, rel_rmse  # noqa: E402

import pcvr_native as pn  # noqa: E402
from pcvr_native import phantoms  # noqa: E402

VIEW = (0.3, -0.5, -0.8)
SUN = pn.Light.sun(direction=(-0.5, -0.2, -0.8))
MAGNIFICATIONS = (1 / 2, 1 / 4, 1 / 8, 1 / 16, 1 / 32, 1 / 64)
LEVELS = (0, 1, 2, 3)
# Level 0 rendered at this many times the pixels each way and box-averaged is the pixel means: what a
# minified image should show (level 0 at the image's own pixels samples the volume at their centres).
SUPERSAMPLING = 4


def ct(n):
    """The CT phantom in Hounsfield units (-1000 + 2000 x its 0..1), air inactive at -1000, and the viewport
    benchmark's bone-like ramp in those units."""
    ph = phantoms.ct_phantom(n)
    hu = np.where(ph.values != 0, -1000.0 + 2000.0 * ph.values, -1000.0).astype(np.float32)
    grid = pn.Grid.from_dense(hu, ph.index_to_world, background=-1000.0)
    tf = pn.TransferFunction(density=[-1000.0, -500.0, 200.0, 1000.0],
                             rgba=[[0, 0, 0, 0], [0.8, 0.5, 0.4, 0.02], [0.9, 0.85, 0.8, 0.3], [1, 1, 1, 0.9]])
    return grid, tf


def blobs(n):
    """Gaussian blobs of 4 to 15 voxels' radius (at 128^3), translucent."""
    return scattered_blobs(n), TRANSLUCENT


def psnr(a, b):
    mse = float(np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2))
    return float("inf") if mse == 0 else 10 * np.log10(1 / mse)


def measure(name, grid, tf, reps, raycast, log, magnifications=MAGNIFICATIONS, sheet_units=("level", "level 0")):
    rows = []
    for mag in magnifications:
        cam = frame_ortho(grid, mag, direction=VIEW).camera()
        shaded = lambda level, spacing, method="pcvr", stats=None: pn.render_shaded(  # noqa: E731
            grid, cam, tf, lights=[SUN], level=level, sheet_spacing=spacing, method=method, threads=1, stats=stats)
        mip = lambda level, spacing, stats=None: pn.render_mip(  # noqa: E731
            grid, cam, level=level, sheet_spacing=spacing, threads=1, stats=stats)
        ref = shaded(0, 1.0)
        mip_ref = mip(0, 1.0) - grid.background
        means = pixel_means(lambda camera: pn.render_shaded(grid, camera, tf, lights=[SUN], threads=1), cam,
                            SUPERSAMPLING)
        truth = shaded(0, 0.1, "raycast") if raycast else None
        for level in LEVELS:
            for unit, spacing in (("level", 1.0), ("level 0", 2.0 ** -level)):
                if (level == 0 and unit == "level 0") or unit not in sheet_units:
                    continue
                stats = {}
                img = shaded(level, spacing, stats=stats)
                mip_stats = {}
                mip_img = mip(level, spacing, stats=mip_stats) - grid.background
                row = dict(volume=name, magnification=mag, level=level, sheets_in=unit,
                           psnr=psnr(img, ref), rmse=rel_rmse(img, ref), psnr_means=psnr(img, means),
                           psnr_raycast=psnr(img, truth) if truth is not None else None,
                           mip_rmse=rel_rmse(mip_img, mip_ref), voxels=stats["voxels"], mip_voxels=mip_stats["voxels"],
                           ms=1e3 * cpu_seconds(lambda: shaded(level, spacing), reps),
                           mip_ms=1e3 * cpu_seconds(lambda: mip(level, spacing), reps), pixels=cam.width * cam.height)
                rows.append(row)
                log(row)
    return rows


def table(rows):
    lines = ["| volume | magnification | level | sheets in voxels of | PSNR vs level 0 | rel. RMSE | PSNR vs pixel means "
             "| PSNR vs raycast | MIP rel. RMSE | voxels | shaded ms | MIP ms |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        ray = f"{r['psnr_raycast']:.1f}" if r["psnr_raycast"] is not None else "-"
        lines.append(f"| {r['volume']} | 1/{round(1 / r['magnification'])} | {r['level']} | {r['sheets_in']} | "
                     f"{r['psnr']:.1f} | {100 * r['rmse']:.2f}% | {r['psnr_means']:.1f} | {ray} | {100 * r['mip_rmse']:.2f}% | {r['voxels']:,} | "
                     f"{r['ms']:.1f} | {r['mip_ms']:.1f} |")
    return lines


# make bench's share: sheets in the level's voxels (the renderer's choice), no ray-cast reference (minutes).
BENCH_MAGNIFICATIONS = (1 / 2, 1 / 8, 1 / 32)


def run(quick, log):
    """make bench's rows: both volumes at BENCH_MAGNIFICATIONS, every level."""
    import datetime
    import os
    n = 64 if quick else 128
    rows = []
    for name, (grid, tf) in (("CT phantom", ct(n)), ("blobs", blobs(n))):
        log(f"shaded levels: {name} {n}^3")
        rows += measure(f"{name} {n}^3", grid, tf, 1 if quick else 3, False, lambda row: None,
                        magnifications=BENCH_MAGNIFICATIONS, sheet_units=("level",))
    return {"date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"), "load": os.getloadavg()[0],
            "rows": rows}


def section(results) -> list[str]:
    """The benchmark page's section (markdown lines)."""
    if not results:
        return []
    return ["## Shaded and MIP from levels of detail", "",
            "`render_shaded` and `render_mip` at `level=k` (`tests/bench/shaded_levels.py`): the CT phantom in "
            "Hounsfield units with a bone-like transfer function and translucent Gaussian blobs, orthographic and "
            "oblique, sheets one voxel of the level apart. PSNR (dB, peak 1) of premultiplied RGBA against level 0 "
            f"and against level 0's pixel means ({SUPERSAMPLING} x {SUPERSAMPLING} times the pixels, box-averaged: "
            "what a zoomed-out image should show); MIP's relative RMSE above the background against level 0. The "
            "viewport's coarse steps use these levels; automatic ones (`level='auto'`) keep voxels at most 1/8 pixel "
            "(docs/how-it-works.md). Median CPU time of one thread; measured "
            f"{results['date']}, load average {results['load']:.1f}.", ""] + table(results["rows"]) + [""]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="64^3 volumes, one timing repetition")
    parser.add_argument("--no-raycast", action="store_true", help="leave out the ray-cast reference (slow)")
    args = parser.parse_args(argv)
    n = 64 if args.quick else 128
    rows = []
    for name, (grid, tf) in (("CT phantom", ct(n)), ("blobs", blobs(n))):
        rows += measure(f"{name} {n}^3", grid, tf, 1 if args.quick else 3, not args.no_raycast,
                        lambda row: print(row, file=sys.stderr))
    print("\n".join(table(rows)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
