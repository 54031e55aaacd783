#!/usr/bin/env python3
"""Time and error against magnification, from zoomed out (1/128) to zoomed in (8): every splatting method
at level 0, and pcvr from its automatic level of detail, on the smooth 48^3 blobs of
tests/native/test_xray_minification.py, in its oblique view.

| column  | what                                                                                          |
|---------|-----------------------------------------------------------------------------------------------|
| ms      | median CPU time of one render with threads=1 (the machine is shared: CPU time, not wall time)  |
| level   | the level of detail rendered (stats; `auto` rows: chosen by render_xray)                     |
| sub-pixels | the supersampling render_xray chose (stats; 1: none, every voxel integrated over the pixels) |
| voxels  | voxels splatted (stats)                                                                       |
| error   | relative RMSE against the pixel means (`exact` on 8 x 8 sub-pixels per pixel, at least one per |
|         | voxel, three times that below magnification 1; from magnification 2 on, the middle 32 x 32 pixels, |
|         | where the whole image would take minutes)                                                      |

    python tests/bench/minification_bench.py [--quick]     # prints the table
"""

from __future__ import annotations

import datetime
import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1] / "tests"))
sys.path.insert(0, str(HERE.parents[1] / "tests" / "native"))

from timing import cpu_seconds  # noqa: E402

MAGNIFICATIONS = (1 / 128, 1 / 64, 1 / 32, 1 / 16, 1 / 8, 1 / 4, 1 / 2, 1, 2, 4, 8)
RUNS = (("regular", 0), ("pcvr", 0), ("bilinear_spread", 0), ("pcvr", "auto"), ("pcvr", 1), ("pcvr", 2))


def run(quick: bool, log=print) -> dict:
    import pcvr_native as pn
    from test_xray_minification import blobs, central_window, reference_factor, OFFSET, VIEW
    from xray_helpers import frame_ortho, pixel_means, rel_rmse, render

    ph, grid = blobs()
    reps = 3 if quick else 7
    rows = []
    for m in MAGNIFICATIONS[:7] if quick else MAGNIFICATIONS:
        cam = frame_ortho(ph, m, direction=VIEW, offset=OFFSET)
        window = central_window(cam, 32) if m >= 2 else cam
        log(f"minification: magnification {m:g}, {cam.width} x {cam.height}")
        # Below magnification 1, three times the tests' sub-pixels: at reference_factor itself the reference
        # samples one point a voxel, as the supersampled `auto` renders do, and would share their error.
        reference = pixel_means(grid, window, reference_factor(m) * (3 if m < 1 else 1))
        for method, level in RUNS:
            if level not in (0, "auto") and m > 1 / 8:  # fixed coarse levels only where they are an option
                continue
            stats = {}
            seconds = cpu_seconds(lambda: pn.render_xray(grid, cam.camera(), method=method, threads=1, stats=stats,
                                                         level=level), reps)
            error = rel_rmse(render(grid, window, method, level=level), reference)
            rows.append({"magnification": m, "method": method, "requested": level, "level": stats["level"],
                         "width": cam.width, "height": cam.height, "median_s": seconds,
                         "voxels": stats.get("voxels", 0), "supersampling": stats.get("supersampling", 1),
                         "error": error})
    return {"date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"), "n": 48,
            "active_voxels": int(grid.active_voxel_count), "load": os.getloadavg()[0], "rows": rows}


def section(results) -> list[str]:
    """The benchmark page's section (markdown lines)."""
    if not results:
        return []
    lines = ["## Zoomed out: time and error against magnification", "",
             f"Smooth Gaussian blobs ({results['n']}^3, {results['active_voxels']:,} active voxels) in an oblique "
             "orthographic view, from 16 voxels per pixel to 8 pixels per voxel (`tests/bench/minification_bench.py`). "
             "Below one pixel per voxel every footprint is integrated over each pixel's area (`native/src/"
             "pixel_prefilter.h`); `auto` renders from the coarsest level of detail whose voxels project to at most "
             "1/32 pixel, and where its voxels are at most 1/8 pixel renders a sub-pixel per voxel and box-averages "
             "(`native/src/view/level_of_detail.h`); 1 and 2 force a level. The error is against the pixel means "
             f"of `exact`. Median CPU time of one thread; measured {results['date']}, load average {results['load']:.1f}.",
             "", "| magnification | image | method | level | sub-pixels | ms | voxels splatted | error |",
             "|---|---|---|---|---|---|---|---|"]
    for r in results["rows"]:
        m = r["magnification"]
        label = f"1/{round(1 / m)}" if m < 1 else f"{m:g}"
        level = f"{r['requested']} ({r['level']})" if r["requested"] == "auto" else f"{r['level']}"
        lines.append(f"| {label} | {r['width']} x {r['height']} | {r['method']} | {level} | {r.get('supersampling', 1)} | "
                     f"{r['median_s'] * 1000:.1f} | "
                     f"{r['voxels']:,} | {100 * r['error']:.3f}% |")
    return lines + [""]


if __name__ == "__main__":
    import standalone
    standalone.main(__doc__, run, section)
