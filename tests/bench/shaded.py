"""Shaded rendering: the paper's Fig 10a on a CT-like phantom, PCVR's perspective targets, and the
peers (VTK, Cycles, EEVEE) with the same transfer function, sun and camera, all in one run.

| step        | what                                                                                   |
|-------------|----------------------------------------------------------------------------------------|
| volume      | ``phantoms.ct_phantom(256)`` (quick: 64), written once as .vdb for the peers           |
| Fig 10a     | oblique orthographic views (views.oblique) at magnifications 1 to 8: the native methods |
|             | of methods.SHADED timed by evidence.time_native (order rotated every repetition,       |
|             | medians), each image compared with regular splatting's, whole; at m=4 also the variants |
|             | (a finer subgrid) that show what meeting the targets would take                        |
| perspective | square images the phantom fills (views.perspective), 512, 1024 and 2048 pixels a side |
|             | (quick: 128, 256): PCVR and regular splatting; VTK at every size, Cycles and EEVEE at   |
|             | the smallest (they take seconds to minutes; peers/budget.py skips what will not fit)   |
| reference   | ``method="raycast"`` every REFERENCE_SPACING voxels, at every `step`-th pixel, `step` a |
|             | prime dividing no subgrid stride (the samples cover every subgrid phase), rendered     |
|             | after the timed renders; its opacity cutoff is the splatting methods' (0.99)           |
| errors      | PSNR of premultiplied RGBA (peak 1) at the reference's pixels, and of alpha alone (the |
|             | coverage, the one quantity every peer's model shares with PCVR's)                       |

Everything lands in ``results["shaded"]``, which shaded_report.py turns into the page's section.
"""

from __future__ import annotations

import dataclasses
import math
import statistics
import time
from pathlib import Path

import numpy as np

import datasets
import evidence
import methods
import peers
import views

# The scene every renderer gets. A bone-like transfer function: transparent below 0.45 (the brain,
# 0.2, and the lesions, 0.3, vanish), a warm translucent ramp, the skull (1.0) near-opaque. Its
# unit_distance is the voxel spacing, filled in per phantom.
SCENE = {
    "transfer_function": {"density": [0.0, 0.45, 0.6, 1.0],
                          "rgba": [[0, 0, 0, 0], [0.8, 0.4, 0.3, 0.0], [0.9, 0.8, 0.6, 0.2], [1, 1, 1, 0.9]]},
    "sun": {"direction": [-0.5, -0.2, -0.8], "color": [1.0, 1.0, 1.0], "strength": 1.0},  # from the upper left
    "ambient": [0.1, 0.1, 0.1],
    "shading": {"ambient": 0.1, "diffuse": 0.9, "specular": 0.2, "shininess": 10.0},
}
SIZE, QUICK_SIZE = 256, 64
MAGNIFICATIONS, QUICK_MAGNIFICATIONS = (1, 2, 3, 4, 5, 6, 7, 8), (1, 2, 4)
SQUARES, QUICK_SQUARES = (512, 1024, 2048), (128, 256)
PERSPECTIVE_METHODS = ("pcvr", "regular")
# The ray caster's samples converge by 0.1 voxel: on this phantom at m=4, 0.1 and 0.05 give images
# 60 dB apart, and every splatting method's PSNR against them agrees to 0.02 dB.
REFERENCE_SPACING = 0.1
REFERENCE_SIDE = 160  # reference samples per image side, about
NATIVE_BUDGET_S = 3.0  # timed seconds per method and view (at least 3 runs)
VARIANT_VIEW = "m4"    # where methods.SHADED's variants run
STAGES = ("plan", "splat", "post_convolution", "shading")
COUNTS = ("blocks", "blocks_outside", "blocks_transparent", "blocks_listed", "voxels", "voxels_occluded", "sheets",
          "tiles", "tiles_terminated", "tile_sheets_composited", "tile_sheets_skipped")


class Scene:
    """SCENE as pcvr_native objects, and the render function evidence.time_native calls."""

    def __init__(self, spec: dict):
        import pcvr_native as pn
        tf = spec["transfer_function"]
        self.tf = pn.TransferFunction(density=tf["density"], rgba=tf["rgba"], unit_distance=tf["unit_distance"])
        self.lights = [pn.Light.sun(direction=spec["sun"]["direction"], color=spec["sun"]["color"],
                                    strength=spec["sun"]["strength"])]
        self.ambient = tuple(spec["ambient"])
        self.shading = pn.Shading(**spec["shading"])

    def render(self, grid, cam, params: dict, **kw):
        """(premultiplied RGBA, wall seconds, stats with the process's CPU seconds as cpu_s)."""
        import pcvr_native as pn
        stats: dict = {}
        c0, t0 = time.process_time(), time.perf_counter()
        options = {k: params[k] for k in ("post_filter", "stride") if k in params}
        img = pn.render_shaded(grid, cam, self.tf, lights=self.lights, ambient=self.ambient, shading=self.shading,
                               method=params["method"], stats=stats, **options, **kw)
        seconds = time.perf_counter() - t0
        stats["cpu_s"] = time.process_time() - c0
        return img, seconds, stats


def psnr(image, reference) -> float:
    """PSNR in dB of premultiplied RGBA (or any channels) in [0, 1], peak 1."""
    mse = float(np.mean((np.asarray(image, dtype=np.float64) - np.asarray(reference, dtype=np.float64)) ** 2))
    return float("inf") if mse == 0 else 10.0 * math.log10(1.0 / mse)


def errors(image, reference, step: int) -> dict:
    """PSNR of RGBA and of alpha against the reference's samples, at the same pixels, and the image's
    brightness where the reference is opaque (its mean RGB over pixels of alpha above one half)."""
    sample = np.asarray(image)[::step, ::step]
    if sample.shape != reference.shape:
        raise RuntimeError(f"sampled image {sample.shape} and reference {reference.shape} differ in shape")
    return {"psnr": psnr(sample, reference), "psnr_alpha": psnr(sample[..., 3], reference[..., 3]),
            "mean_lit": brightness(sample, reference)}


def brightness(image, reference) -> float:
    opaque = np.asarray(reference)[..., 3] > 0.5
    return float(np.asarray(image, dtype=np.float64)[..., :3][opaque].mean()) if opaque.any() else float("nan")


def is_prime(n: int) -> bool:
    return n >= 2 and all(n % d for d in range(2, int(math.isqrt(n)) + 1))


def reference_step(view: dict, strides) -> int:
    """The smallest prime near REFERENCE_SIDE samples per side that divides no subgrid stride."""
    step = max(2, math.ceil(max(view["width"], view["height"]) / REFERENCE_SIDE))
    while not is_prime(step) or any(s % step == 0 for s in strides):
        step += 1
    return step


def method_record(entry: dict, active: int) -> dict:
    """Times, the first run's counts and the median of each stage's thread seconds."""
    runs = entry["stats"]
    first = runs[0]
    median = statistics.median(entry["times"])
    return {"times": entry["times"], "runs": len(entry["times"]), "median_s": median,
            "cpu_s": statistics.median(s["cpu_s"] for s in runs),
            "stage_s": {st: statistics.median(s[f"seconds_{st}"] for s in runs) for st in STAGES},
            "counts": {k: first[k] for k in COUNTS}, "strides": first["strides"],
            "active_mvox_per_s": active / median / 1e6, "deposit_mvox_per_s": first["voxels"] / median / 1e6}


def bench_views(grid, scene: Scene, view_set: dict, table, args, active: int, keep: set, workdir: Path, log) -> dict:
    """Time the native methods on each view, then render its reference and measure every image."""
    out = {}
    for vk, view in view_set.items():
        cam = views.camera(view)
        timed = evidence.time_native(grid, cam, [m for m in table if vk == VARIANT_VIEW or not m.params.get("variant")],
                                     args.quick, render=scene.render, budget_s=NATIVE_BUDGET_S)
        regular = timed["regular"]["image"]
        strides = sorted({s for e in timed.values() for s in e["stats"][0]["strides"]})
        step = reference_step(view, strides)
        reference, ref_s, _ = scene.render(grid, cam, {"method": "raycast"}, sheet_spacing=REFERENCE_SPACING,
                                           pixel_step=step)
        rec = out[vk] = {"width": view["width"], "height": view["height"], "type": view["type"],
                         "magnification": view["magnification"],
                         "reference": {"step": step, "seconds": ref_s, "mean_lit": brightness(reference, reference)},
                         "methods": {}}
        for key, entry in timed.items():
            m = rec["methods"][key] = method_record(entry, active)
            m["vs_reference"] = errors(entry["image"], reference, step)
            m["psnr_vs_regular"] = psnr(entry["image"], regular) if key != "regular" else float("inf")
            if vk in keep:
                m["image_path"] = str(workdir / f"{key}_{vk}.npy")
                np.save(m["image_path"], np.asarray(entry["image"], dtype=np.float32))
        rec["reference"]["image_path"] = str(workdir / f"reference_{vk}.npy")  # for the peers and the figures
        np.save(rec["reference"]["image_path"], reference)
        log(f"  {vk} {view['width']}x{view['height']} (reference every {step} px, {ref_s:.1f} s): " + ", ".join(
            f"{k} {1e3 * m['median_s']:.0f} ms {m['vs_reference']['psnr']:.1f} dB" for k, m in rec["methods"].items()))
        del timed, regular
    return out


def run_peers(scene_spec: dict, vdb: Path, view_set: dict, table, views_for: dict, args, workdir: Path, out: dict,
              log) -> None:
    """Every peer of `table` on its runner's views (`views_for[runner]`), each image against the
    view's reference."""
    budget = methods.PEER_BUDGET_QUICK_S if args.quick else methods.PEER_BUDGET_S
    for runner in ("vtk", "blender"):
        vset = {vk: view_set[vk] for vk in views_for[runner]}
        configs = []
        for m in (m for m in table if m.runner == runner and m.key not in args.skip_peers):
            if args.quick and m.params.get("slow"):
                for vk in vset:
                    out["views"][vk]["methods"][m.key] = {"skipped": "not on the quick run (seconds even on its small volume)"}
            else:
                configs.append(dict(m.params, key=m.key))
        if not configs:
            continue
        job = {"mode": "shaded", "vdb": str(vdb), "views": vset, "scene": scene_spec, "configs": configs,
               "budget_s": budget, "projections": {vk: views.matrices(v)[1].tolist() for vk, v in vset.items()}}
        log(f"  {runner} peers: {len(configs)} configurations on {', '.join(vset)}")
        recs = peers.run(runner, job, workdir / runner, timeout_s=args.peer_timeout, log=log)
        for (key, vk), rec in recs.items():
            view = out["views"][vk]
            if "skipped" in rec:
                view["methods"][key] = {"skipped": rec["skipped"]}
                continue
            step = view["reference"]["step"]
            reference = np.load(view["reference"]["image_path"])
            view["methods"][key] = {
                "times": rec["seconds"], "runs": len(rec["seconds"]), "median_s": statistics.median(rec["seconds"]),
                "cpu_s": statistics.median(rec["cpu_seconds"]),
                "vs_reference": errors(np.load(rec["image"]), reference, step), "image_path": rec["image"],
                **{k: rec[k] for k in ("warmup_s", "camera_error", "software") if k in rec}}


def run(args, workdir: Path, log) -> dict:
    import pcvr_native as pn
    from pcvr_native import phantoms
    workdir.mkdir(parents=True, exist_ok=True)
    n = QUICK_SIZE if args.quick else SIZE
    phantom = phantoms.ct_phantom(n)
    grid = pn.Grid.from_dense(phantom.values, phantom.index_to_world, 0.0)
    vdb = workdir / "ct.vdb"
    grid.write_vdb(str(vdb), "density")
    spec = {**SCENE, "transfer_function": {**SCENE["transfer_function"], "unit_distance": datasets.voxel_spacing(phantom)}}
    scene = Scene(spec)
    active = int(grid.active_voxel_count)
    table = methods.SHADED
    native = [m for m in table if m.runner == "native"]
    squares = QUICK_SQUARES if args.quick else SQUARES
    mags = QUICK_MAGNIFICATIONS if args.quick else MAGNIFICATIONS
    shape = phantom.values.shape
    ortho = {f"m{m}": views.oblique(shape, phantom.index_to_world, m) for m in mags}
    persp = {f"p{s}": views.perspective(shape, phantom.index_to_world, square=s) for s in squares}
    out = {"label": "CT head phantom", "n": n, "active_voxels": active, "scene": spec, "pixel_views": list(persp),
           "reference_spacing": REFERENCE_SPACING, "methods": [dataclasses.asdict(m) for m in table],
           "views": {}, "peer_views": {"vtk": list(persp), "blender": [min(persp, key=lambda k: persp[k]["width"])]}}
    log(f"shaded: CT phantom {n}^3, {active} active voxels")
    pn.render_shaded(grid, views.camera(ortho[next(iter(ortho))]), scene.tf, method="pcvr")  # block cache, once
    side = out["peer_views"]["blender"][0]
    out["views"].update(bench_views(grid, scene, ortho, native, args, active, {"m4"}, workdir, log))
    persp_native = [m for m in native if m.key in PERSPECTIVE_METHODS]
    out["views"].update(bench_views(grid, scene, persp, persp_native, args, active, {side}, workdir, log))
    run_peers(spec, vdb, persp, table, out["peer_views"], args, workdir, out, log)
    return out
