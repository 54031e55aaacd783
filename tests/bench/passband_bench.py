#!/usr/bin/env python3
"""The passband compensation (native/src/splat/passband.h) and the post filter's mass, before and after.

| part  | what                                                                                              |
|-------|---------------------------------------------------------------------------------------------------|
| truth | pcvr and regular with `passband="paper"` and `"compensated"`, and `exact`, against the line       |
|       | integrals of the signal that was sampled, in an orthographic view at magnifications 1 to          |
|       | 4, each at three sub-voxel camera offsets (relative RMSE, mean and worst over the offsets): the   |
|       | Gaussian blobs of datasets.py (64^3, sigma 1.2-4 voxels; analytic) and Marschner-Lobb (41^3,      |
|       | content up to 0.47 cycles per voxel, next to the stop band; the continuous signal integrated       |
|       | along each ray, Simpson's rule, seen nearly along z, over the pixels whose rays stay inside the   |
|       | volume's sides)                                                                                   |
| mass  | one column of 20000 voxels seen end-on, m = 1.125 to 5.7, three sub-voxel offsets: worst error    |
| time  | the 128^3 blobs at m = 1, 1.125, 2, 4 on one thread: least CPU time of REPS renders of each       |
|       | passband, the two alternated in one sitting                                                       |

    python tests/bench/passband_bench.py [--quick]     # prints the section
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import datasets  # noqa: E402
import views  # noqa: E402

MAGNIFICATIONS = (1.0, 1.125, 1.5, 2.0, 2.5, 4.0)
OFFSETS = ((0.0, 0.0), (0.25, 0.1), (0.5, 0.37))  # of a voxel
RENDERS = (("pcvr", "paper"), ("pcvr", "compensated"), ("regular", "paper"), ("regular", "compensated"),
           ("exact", "paper"))
COLUMN = 20000
COLUMN_MAGNIFICATIONS = (1.125, 1.3, 1.5, 2.0, 2.2, 2.5, 3.3, 4.0, 5.7)
TIME_SIZE = 128
TIME_MAGNIFICATIONS = (1.0, 1.125, 2.0, 4.0)
REPS = 7


# Marschner-Lobb is seen nearly along its z axis: its rays then cross the volume through the slab |z| <= 1 only,
# where the truth below integrates (the volume's sides cut the signal off).
ML_DIRECTION, ML_UP = (0.08, 0.05, -1.0), (0.0, 1.0, 0.0)


def oblique(phantom, magnification: float, offset, direction=views.VIEW_DIRECTION, up=views.VIEW_UP) -> "pn.Camera":
    """views.py's oblique camera moved by `offset` voxels (in pixels: offset times the magnification)."""
    import pcvr_native as pn
    view = views.oblique(phantom.values.shape, phantom.index_to_world, magnification, direction, up)
    w2c, proj = views.matrices(view)
    shift = np.eye(4)
    shift[0, 3] = -2.0 * offset[0] * magnification / view["width"]
    shift[1, 3] = -2.0 * offset[1] * magnification / view["height"]
    return pn.Camera(w2c, shift @ proj, view["width"], view["height"])


def marschner_lobb_signal(p: np.ndarray, f_m: float = 6.0, alpha: float = 0.25) -> np.ndarray:
    """The continuous signal phantoms.marschner_lobb samples."""
    r = np.sqrt(p[..., 0] ** 2 + p[..., 1] ** 2)
    return (1.0 - np.sin(math.pi * p[..., 2] / 2.0) + alpha * (1.0 + np.cos(2.0 * math.pi * f_m * np.cos(math.pi * r / 2.0)))
            ) / (2.0 * (1.0 + alpha))


def marschner_lobb_truth(camera, spacing: float, samples: int = 801):
    """Line integrals of the signal through the slab |z| <= 1 + spacing / 2 (the sampled volume and the half
    voxel its kernels reach past the last samples), and the pixels whose rays keep |x|, |y| < 0.8 there."""
    from pcvr_native import phantoms
    o, d = phantoms.pixel_rays(camera)
    z0, z1 = 1.0 + spacing / 2, -1.0 - spacing / 2
    t0, t1 = (z0 - o[..., 2]) / d[..., 2], (z1 - o[..., 2]) / d[..., 2]
    weights = np.ones(samples)
    weights[1:-1:2], weights[2:-1:2] = 4.0, 2.0
    weights /= weights.sum()
    total = np.zeros(o.shape[:2])
    for w, s in zip(weights, np.linspace(0.0, 1.0, samples)):
        total += w * marschner_lobb_signal(o + (t0 + s * (t1 - t0))[..., None] * d)
    inside = np.ones(total.shape, dtype=bool)
    for t in (t0, t1):
        p = o + t[..., None] * d
        inside &= (np.abs(p[..., 0]) < 0.8) & (np.abs(p[..., 1]) < 0.8)
    return total * np.abs(t1 - t0), inside


def rel_rmse(a, b) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)) / np.sqrt(np.mean(b ** 2)))


def truth_errors(quick: bool, log) -> dict:
    import pcvr_native as pn
    from pcvr_native import phantoms
    ds = datasets.BY_KEY["blobs"]
    blobs = ds.phantom(quick)
    ml = phantoms.marschner_lobb(41)
    mags = MAGNIFICATIONS[::2] if quick else MAGNIFICATIONS
    offsets = OFFSETS[:1] if quick else OFFSETS
    out = {}
    for key, phantom in (("blobs", blobs), ("ml", ml)):
        grid = phantom.grid()
        rows = []
        for m in mags:
            log(f"passband: {key} at m={m:g}")
            errors = {f"{method}/{passband}": [] for method, passband in RENDERS}
            for offset in offsets:
                cam = oblique(phantom, m, offset) if key == "blobs" else oblique(phantom, m, offset, ML_DIRECTION, ML_UP)
                if key == "blobs":
                    truth, inside = ds.truth(phantom, cam, quick=quick), slice(None)
                else:
                    truth, inside = marschner_lobb_truth(cam, 2.0 / 40)
                for method, passband in RENDERS:
                    img = np.asarray(pn.render_xray(grid, cam, method, passband=passband), dtype=np.float64)
                    errors[f"{method}/{passband}"].append(rel_rmse(img[inside], truth[inside]))
            rows.append({"magnification": m, "mean": {k: float(np.mean(v)) for k, v in errors.items()},
                         "worst": {k: float(np.max(v)) for k, v in errors.items()}})
        out[key] = {"size": phantom.values.shape[0], "rows": rows}
    return out


def column_mass(quick: bool) -> dict:
    import pcvr_native as pn
    from pcvr_native.cameras import look_at, ortho
    grid = pn.Grid.from_dense(np.ones((1, 1, COLUMN), dtype=np.float32), np.eye(4))
    w2c = look_at((0.0, 0.0, COLUMN + 10.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    worst = {}
    for m in COLUMN_MAGNIFICATIONS[::3] if quick else COLUMN_MAGNIFICATIONS:
        px, half = 1.0 / m, int(12 * m) + 8
        for ox, oy in OFFSETS:
            cx, cy = ox * px, oy * px
            cam = pn.Camera(w2c, ortho(-half * px + cx, half * px + cx, -half * px + cy, half * px + cy, 1.0, COLUMN + 20.0),
                            2 * half, 2 * half)
            for method, passband in RENDERS[:4]:
                img = np.asarray(pn.render_xray(grid, cam, method, passband=passband), dtype=np.float64)
                err = abs(img.sum() * px * px / COLUMN - 1.0)
                key = f"{method}/{passband}"
                worst[key] = max(worst.get(key, 0.0), err)
    return worst


def xray_times(quick: bool, log) -> dict:
    import pcvr_native as pn
    phantom = datasets.BY_KEY["blobs"].make(64 if quick else TIME_SIZE)
    grid = phantom.grid()
    reps = 2 if quick else REPS
    rows = []
    for m in TIME_MAGNIFICATIONS:
        log(f"passband: time at m={m:g}")
        cam = views.camera(views.oblique(phantom.values.shape, phantom.index_to_world, m))
        for method in ("pcvr", "regular"):
            least = {"paper": math.inf, "compensated": math.inf}
            pn.render_xray(grid, cam, method, threads=1)  # warm-up
            for rep in range(reps):
                for passband in (("paper", "compensated") if rep % 2 else ("compensated", "paper")):
                    t0 = time.thread_time()
                    pn.render_xray(grid, cam, method, threads=1, passband=passband)
                    least[passband] = min(least[passband], time.thread_time() - t0)
            rows.append({"magnification": m, "method": method, "image": [cam.width, cam.height], **least})
    return {"size": phantom.values.shape[0], "voxels": int(grid.active_voxel_count), "reps": reps, "rows": rows}


def run(quick: bool, log) -> dict:
    load_before = os.getloadavg()[0]
    out = {"date": time.strftime("%Y-%m-%d %H:%M"), "truth": truth_errors(quick, log), "mass": column_mass(quick),
           "time": xray_times(quick, log)}
    out["load"] = [load_before, os.getloadavg()[0]]
    return out


def section(results) -> list[str]:
    """The benchmark page's section (markdown lines)."""
    if not results:
        return []
    names = {"blobs": "Gaussian blobs, analytic line integrals", "ml": "Marschner-Lobb, line integrals of its signal"}
    lines = ["## Passband compensation: error against the truth, mass, time", "",
             "`render_xray(..., passband=\"compensated\")` (the default) sharpens the splat grid by [−a, 1 + 2a, −a] "
             "along each axis of nodes a projected voxel apart, with a = 1.1 / 2 times the blur it pays back: the splat "
             "kernel's variance, and for pcvr the post filter's mean blur (`native/src/splat/passband.h`); "
             "`passband=\"paper\"` keeps the paper's pair. Errors are relative RMSE against the line integrals of the "
             "signal that was sampled (no reconstruction kernel), mean over three sub-voxel camera offsets (worst in "
             "brackets), oblique orthographic views (`tests/bench/passband_bench.py`). Measured "
             f"{results['date']}, load average {results['load'][0]:.1f} before and {results['load'][1]:.1f} after.", ""]
    for key, data in results["truth"].items():
        lines += [f"**{names[key]}** ({data['size']}³):", "",
                  "| m | pcvr, paper | pcvr, compensated | regular, paper | regular, compensated | exact |",
                  "|---:|---:|---:|---:|---:|---:|"]
        for row in data["rows"]:
            cells = [f"{100 * row['mean'][k]:.2f}% ({100 * row['worst'][k]:.2f}%)"
                     for k in ("pcvr/paper", "pcvr/compensated", "regular/paper", "regular/compensated", "exact/paper")]
            lines.append(f"| {row['magnification']:g} | " + " | ".join(cells) + " |")
        lines.append("")
    mass = results["mass"]
    lines += [f"**Mass**: one column of {COLUMN:,} voxels seen end-on, m = 1.125 to 5.7, three sub-voxel offsets, worst "
              "error of the image's integral: " + ", ".join(f"{k} {100 * v:.2f}%" for k, v in mass.items()) +
              " (pcvr before the post filter was averaged over each pixel at fractional strides: up to 7.4%).", "",
              f"**Time** (the {results['time']['size']}³ blobs, {results['time']['voxels']:,} active voxels, one thread, "
              f"least CPU time of {results['time']['reps']} renders each, the two passbands alternated):", "",
              "| m | image | method | paper | compensated | ratio |", "|---:|---|---|---:|---:|---:|"]
    for r in results["time"]["rows"]:
        lines.append(f"| {r['magnification']:g} | {r['image'][0]} × {r['image'][1]} | {r['method']} | "
                     f"{1000 * r['paper']:.2f} ms | {1000 * r['compensated']:.2f} ms | {r['compensated'] / r['paper']:.3f} |")
    return lines + [""]


if __name__ == "__main__":
    import standalone
    standalone.main(__doc__, run, section)
