"""Time against error: every method and peer of a mode on every data set and view, in one run.

For each volume of datasets.py the .vdb file is written once and every renderer reads that file (or,
for VTK, its values) through the cameras of views.py. Per view:

| step       | what                                                                                      |
|------------|-------------------------------------------------------------------------------------------|
| references | ``exact`` at every PIXEL_STEP-th pixel (double precision, analytic footprints; 7 is       |
|            | co-prime with every subgrid stride, so the samples cover all phases), and for the blobs   |
|            | the analytic X-ray of the continuous Gaussians (no reconstruction kernel)                  |
| native     | PCVR and the other splatting methods, each run in an order rotated every repetition,     |
|            | median of up to REPS runs (at least MIN_REPS)                                              |
| peers      | Cycles and EEVEE (one Blender child), VTK (one child): see peers/                         |
| errors     | each image at the sampled pixels against exact (and the truth): relative RMSE, PSNR       |

Everything lands in one results dict (``results["xray"]``) that report.py and the plots read.
"""

from __future__ import annotations

import dataclasses
import math
import statistics
import time
from pathlib import Path

import numpy as np

import datasets
import methods
import peers
import views

PIXEL_STEP = 7
REPS, MIN_REPS = 7, 3
NATIVE_BUDGET_S = 6.0  # timed seconds per method and view, shared out as runs


def error_metrics(image, reference, sampled: bool = False) -> dict:
    """Relative RMSE and PSNR of `image` at every PIXEL_STEP-th pixel (all of it when `sampled`)
    against `reference` samples. PSNR's peak is the reference's largest magnitude."""
    sample = np.asarray(image, dtype=np.float64)
    sample = sample if sampled else sample[::PIXEL_STEP, ::PIXEL_STEP]
    ref = np.asarray(reference, dtype=np.float64)
    if sample.shape != ref.shape:
        raise RuntimeError(f"sampled image {sample.shape} and reference samples {ref.shape} differ in shape")
    rmse = float(np.sqrt(np.mean((sample - ref) ** 2)))
    rms = float(np.sqrt(np.mean(ref ** 2)))
    peak = float(np.max(np.abs(ref)))
    return {"rel_rmse": rmse / rms if rms > 0 else float("nan"),
            "psnr": 20.0 * math.log10(peak / rmse) if rmse > 0 else float("inf")}


def render_native(grid, cam, params: dict):
    import pcvr_native as pn
    stats: dict = {}
    t0 = time.perf_counter()
    img = pn.render_xray(grid, cam, params["method"], params["splat_kernel"], params["post_filter"], 0, 0,
                         stats=stats, passband=params.get("passband", "compensated"))
    return img, time.perf_counter() - t0, stats


def time_native(grid, cam, table, quick: bool, render=render_native, budget_s: float = NATIVE_BUDGET_S):
    """Each native method: first image, the stats of every run and run times (orders rotated per
    repetition; as many runs as fit `budget_s` seconds per method, within REPS and MIN_REPS).
    `render(grid, cam, params)` returns (image, seconds, stats)."""
    out = {m.key: {"times": [], "stats": []} for m in table}
    keys = [m.key for m in table]
    reps = None
    rep = 0
    while True:
        ran = False
        for key in keys[rep % len(keys):] + keys[:rep % len(keys)]:
            entry = out[key]
            if reps is not None and len(entry["times"]) >= reps[key]:
                continue
            img, t, stats = render(grid, cam, next(m for m in table if m.key == key).params)
            entry["times"].append(t)
            entry["stats"].append(stats)
            if rep == 0:
                entry["image"], entry["stride"] = img, stats.get("stride")
            ran = True
        if not ran:
            break
        if rep == 0:
            hi, lo = (3, 1) if quick else (REPS, MIN_REPS)
            reps = {k: max(lo, min(hi, int(budget_s / max(v["times"][0], 1e-9)))) for k, v in out.items()}
        rep += 1
    return out


def bench_dataset(ds: datasets.Dataset, table, args, workdir: Path, log) -> dict:
    import pcvr_native as pn
    phantom = ds.phantom(args.quick)
    grid = pn.Grid.from_dense(phantom.values, phantom.index_to_world, 0.0)
    vdb = workdir / ds.key / "volume.vdb"
    vdb.parent.mkdir(parents=True, exist_ok=True)
    grid.write_vdb(str(vdb), "density")
    view_set = views.views_for(phantom, args.magnifications, with_perspective=True)
    n = phantom.values.shape[0]
    out = {"label": ds.label, "what": ds.what, "n": n, "active_voxels": int(grid.active_voxel_count),
           "has_truth": ds.blobs is not None, "views": {}}
    log(f"{ds.label} {n}^3: {out['active_voxels']} active voxels")

    references = {}
    for vk, view in view_set.items():
        cam = views.camera(view)
        t0 = time.perf_counter()
        exact = np.asarray(pn.render_xray(grid, cam, "exact", pixel_step=PIXEL_STEP), dtype=np.float64)
        truth = ds.truth(phantom, cam, PIXEL_STEP, args.quick)
        references[vk] = (exact, truth)
        out["views"][vk] = {"width": view["width"], "height": view["height"], "magnification": view["magnification"],
                            "type": view["type"], "exact_s": time.perf_counter() - t0, "methods": {}}
        if truth is not None:
            out["views"][vk]["exact_vs_truth"] = error_metrics(exact, truth, sampled=True)
    integral_max = max(float(r[0].max()) for r in references.values())

    def record(vk, key, image, seconds, **extra):
        exact, truth = references[vk]
        rec = {"times": seconds, "runs": len(seconds), "median_s": statistics.median(seconds),
               "vs_exact": error_metrics(image, exact), **extra}
        if truth is not None:
            rec["vs_truth"] = error_metrics(image, truth)
        out["views"][vk]["methods"][key] = rec
        return rec

    native = [m for m in table if m.runner == "native"]
    keep_images = args.keep_images.get(ds.key, set())
    for vk, view in view_set.items():
        timed = time_native(grid, views.camera(view), native, args.quick)
        for key, entry in timed.items():
            rec = record(vk, key, entry["image"], entry["times"], stride=entry["stride"])
            if vk in keep_images:
                rec["image_path"] = str(workdir / ds.key / f"{key}_{vk}.npy")
                np.save(rec["image_path"], np.asarray(entry["image"], dtype=np.float32))
        log(f"  {vk} {view['width']}x{view['height']}: " + ", ".join(
            f"{k} {1e3 * out['views'][vk]['methods'][k]['median_s']:.1f} ms "
            f"{100 * out['views'][vk]['methods'][k]['vs_exact']['rel_rmse']:.2f}%" for k in timed))

    projections = {vk: views.matrices(v)[1].tolist() for vk, v in view_set.items()}
    budget = methods.PEER_BUDGET_QUICK_S if args.quick else methods.PEER_BUDGET_S
    for runner in ("blender", "vtk"):
        configs = [dict(m.params, key=m.key) for m in table if m.runner == runner and m.key not in args.skip_peers]
        if not configs:
            continue
        job = {"vdb": str(vdb), "views": view_set, "projections": projections, "configs": configs, "budget_s": budget,
               "integral_max": integral_max}
        log(f"  {runner} peers: {len(configs)} configurations")
        recs = peers.run(runner, job, workdir / ds.key / runner, timeout_s=args.peer_timeout, log=log)
        for (key, vk), rec in recs.items():
            if "skipped" in rec:
                out["views"][vk]["methods"][key] = {"skipped": rec["skipped"]}
                continue
            image = np.load(rec["image"])
            extra = {k: rec[k] for k in ("camera_error", "min_transmittance", "saturated", "software") if k in rec}
            extra["image_path"] = rec["image"]
            record(vk, key, image, rec["seconds"], **extra)
    return out


def run(args, workdir: Path, log) -> dict:
    table = methods.MODES["xray"]
    results = {"pixel_step": PIXEL_STEP, "methods": [dataclasses.asdict(m) for m in table], "datasets": {}}
    for ds in datasets.DATASETS:
        if ds.key in args.datasets:
            results["datasets"][ds.key] = bench_dataset(ds, table, args, workdir, log)
    return results
