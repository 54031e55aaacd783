#!/usr/bin/env python3
"""Shaded rendering of a real CT head against VTK's fixed-point CPU ray caster, at 512^2 to 2048^2.

| step        | what                                                                                        |
|-------------|---------------------------------------------------------------------------------------------|
| volume      | ct_head_data: a real CT head (256 x 256 x 108, voxels 0.96 x 0.96 x 1.5 mm, Hounsfield units),|
|             | air (-1024) the background; written once as .vdb for VTK                                    |
| scenes      | TRANSFER_FUNCTIONS: "translucent" (soft tissue faint, bone partly opaque: rays cross the head) |
|             | and "bone" (air and soft tissue clear, bone opaque); one sun, Blinn-Phong 0.2 / 0.8 / 0.3 / 20 |
| views       | square perspective images the head fills (views.perspective), 512, 1024, 2048 px (quick: 128,  |
|             | 256)                                                                                        |
| methods     | `pcvr` and `regular` (2 threads), VTK fixed-point at sample distances 1 and 0.5 voxel (its     |
|             | threads: the machine's 2 cores), in ROUNDS alternating rounds (native, then VTK's child)     |
| errors      | PSNR of premultiplied RGBA (peak 1) against `method="raycast"` (steps of 0.1 voxel, at every  |
|             | `step`-th pixel, as shaded.py), and PCVR's against `regular`'s whole image                 |

Times are the least wall seconds over the rounds (the machine is shared: other work only adds).
Everything lands in ``results["ct_head"]``; section() writes the page's table.

    python tests/bench/ct_head.py [--quick]      # prints the section
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.append(str(HERE))

import ct_head_data  # noqa: E402
import peers  # noqa: E402
import views  # noqa: E402
from shaded import errors, psnr, reference_step  # noqa: E402

AIR = ct_head_data.AIR_HU
# Hounsfield units; opacity per millimetre (unit_distance 1, about a voxel).
TRANSFER_FUNCTIONS = {
    "translucent": {"density": [AIR, -200.0, 40.0, 300.0, 1500.0],
                    "rgba": [[0, 0, 0, 0], [0.8, 0.5, 0.4, 0.0], [0.8, 0.5, 0.4, 0.01], [0.9, 0.85, 0.8, 0.05],
                             [1, 1, 1, 0.3]], "unit_distance": 1.0},
    "bone": {"density": [AIR, 150.0, 400.0, 1000.0],
             "rgba": [[0, 0, 0, 0], [0.9, 0.85, 0.8, 0.0], [0.95, 0.9, 0.85, 0.7], [1, 1, 1, 1]], "unit_distance": 1.0},
}
SUN = {"direction": [-0.5, -0.2, -0.8], "color": [1.0, 1.0, 1.0], "strength": 1.0}
SHADING = {"ambient": 0.2, "diffuse": 0.8, "specular": 0.3, "shininess": 20.0}
AMBIENT = [1.0, 1.0, 1.0]
SQUARES, QUICK_SQUARES = (512, 1024, 2048), (128, 256)
NATIVE = ("pcvr", "regular")
VTK_STEPS = (1.0, 0.5)
THREADS = 2
ROUNDS, QUICK_ROUNDS = 3, 1
REFERENCE_SPACING = 0.1


def scene(tf_key: str) -> dict:
    return {"transfer_function": TRANSFER_FUNCTIONS[tf_key], "sun": SUN, "ambient": AMBIENT, "shading": SHADING}


def native_render(grid, cam, spec: dict, method: str, **kw):
    import pcvr_native as pn
    tf = spec["transfer_function"]
    stats: dict = {}
    t0 = time.perf_counter()
    img = pn.render_shaded(grid, cam, pn.TransferFunction(**tf), lights=[pn.Light.sun(**SUN)], ambient=tuple(AMBIENT),
                           shading=pn.Shading(**SHADING), method=method, threads=THREADS, stats=stats, **kw)
    return img, time.perf_counter() - t0, stats


STAGE_KEYS = ("seconds_splat", "seconds_sampling", "seconds_post_convolution", "seconds_shading", "voxels", "voxels_occluded",
              "taps", "grids_sampled", "sheet_samples", "sheet_samples_skipped",
              "samples_classified", "samples_shaded", "blocks_transparent", "bricks_transparent", "tiles",
              "tiles_terminated", "tile_sheets_composited", "strides", "sampled_strides")


def stage_record(stats: dict) -> dict:
    return {k: stats[k] for k in STAGE_KEYS if k in stats}


def run(quick: bool, log) -> dict:
    import pcvr_native as pn
    try:
        values, index_to_world, meta = ct_head_data.load()
    except ct_head_data.Unavailable as e:
        log(f"CT head: skipped ({e})")
        return {"skipped": str(e), "source": ct_head_data.SOURCE}
    workdir = Path(ct_head_data.CACHE) / "bench"
    workdir.mkdir(parents=True, exist_ok=True)
    grid = pn.Grid.from_dense(values, index_to_world, background=AIR)
    vdb = workdir / "ct_head.vdb"
    grid.write_vdb(str(vdb), "density")
    squares = QUICK_SQUARES if quick else SQUARES
    view_set = {f"p{s}": views.perspective(values.shape, index_to_world, square=s) for s in squares}
    out = {"source": meta["source"], "shape": list(values.shape), "spacing": meta["spacing"],
           "active_voxels": int(grid.active_voxel_count), "threads": THREADS, "scenes": {}}
    log(f"CT head {values.shape}, {out['active_voxels']} active voxels")
    rounds = QUICK_ROUNDS if quick else ROUNDS
    for tf_key in TRANSFER_FUNCTIONS:
        spec = scene(tf_key)
        rec = out["scenes"][tf_key] = {"views": {vk: {"methods": {}} for vk in view_set}}
        images = {}
        for r in range(rounds):
            for vk, view in view_set.items():
                cam = views.camera(view)
                for method in NATIVE if r % 2 == 0 else NATIVE[::-1]:
                    img, seconds, stats = native_render(grid, cam, spec, method)
                    m = rec["views"][vk]["methods"].setdefault(method, {"times": [], "stats": stage_record(stats)})
                    if seconds < min(m["times"], default=float("inf")):
                        m["stats"] = stage_record(stats)  # the fastest run's stage times
                    m["times"].append(seconds)
                    images[vk, method] = img
            job = {"mode": "shaded", "vdb": str(vdb), "views": view_set, "scene": spec, "budget_s": 600.0,
                   "configs": [{"key": f"vtk_fixed_{st:g}", "mapper": "fixed_point", "step": st} for st in VTK_STEPS],
                   "projections": {vk: views.matrices(v)[1].tolist() for vk, v in view_set.items()}}
            for (key, vk), peer in peers.run("vtk", job, workdir / f"vtk_{tf_key}", timeout_s=1800, log=log).items():
                m = rec["views"][vk]["methods"].setdefault(key, {"times": []})
                if "skipped" in peer:
                    m["skipped"] = peer["skipped"]
                    continue
                m["times"].append(min(peer["seconds"]))
                m["image"] = peer["image"]
                m["software"] = peer.get("software", "?")
        for vk, view in view_set.items():
            cam = views.camera(view)
            strides = sorted(set(rec["views"][vk]["methods"]["pcvr"]["stats"].get("strides", [1])))
            step = reference_step(view, strides)
            reference, ref_s, _ = native_render(grid, cam, spec, "raycast", sheet_spacing=REFERENCE_SPACING, pixel_step=step)
            v = rec["views"][vk]
            v["reference_step"] = step
            for key, m in v["methods"].items():
                if m.get("skipped") or not m["times"]:
                    continue
                m["seconds"] = min(m["times"])
                image = images.get((vk, key))
                if image is None:
                    image = np.load(m["image"])
                m["psnr_raycast"] = errors(image, reference, step)["psnr"]
                if key == "pcvr":
                    m["psnr_regular"] = psnr(image, images[vk, "regular"])
            log(f"  {tf_key} {vk}: " + ", ".join(f"{k} {m['seconds']:.3f} s {m['psnr_raycast']:.1f} dB"
                                                   for k, m in v["methods"].items() if "seconds" in m))
    return out


def section(res: dict | None) -> list[str]:
    if res is None:
        return []
    lines = ["## Shaded rendering of a real CT head against VTK", ""]
    lines.append(f"Volume: {res.get('source', ct_head_data.SOURCE)}; fetched into a cache folder at run time, "
                 "never committed.")
    if "skipped" in res:
        return lines + ["", f"Skipped on this run: {res['skipped']}."]
    sx, sy, sz = res["spacing"]
    lines += ["", f"{' x '.join(map(str, res['shape']))} voxels of {sx:.3g} x {sy:.3g} x {sz:.3g} mm, "
              f"{res['active_voxels']:,} active; {res['threads']} threads for every renderer; square perspective "
              "images the head fills; least wall seconds of the rounds (native and VTK rounds alternate). VTK: "
              "`vtkFixedPointVolumeRayCastMapper`, sample distance 1 and 0.5 voxel (the voxel's geometric mean), "
              "frame-rate adaptation off. PSNR (dB) of premultiplied RGBA against PCVR's ray caster "
              f"(steps of {REFERENCE_SPACING} voxel); `pcvr` also against `regular`.", ""]
    lines += aims(res) + [""]
    for tf_key, sc in res["scenes"].items():
        tf = TRANSFER_FUNCTIONS[tf_key]
        lines += [f"### Transfer function \"{tf_key}\"", "",
                  "Points (HU: RGBA per mm): " + ", ".join(f"{d:g}: {tuple(c)}" for d, c in zip(tf["density"], tf["rgba"])), "",
                  "| image | VTK step 1 (s) | VTK step 0.5 (s) | `pcvr` (s) | `regular` (s) | VTK 1 / `pcvr` | VTK 0.5 / `pcvr` "
                  "| `regular` / `pcvr` | PSNR VTK 1 / `pcvr` / `regular` | `pcvr` vs `regular` | `pcvr` splat / sampling / post / shading thread-s |",
                  "|---|---|---|---|---|---|---|---|---|---|---|"]
        for vk, v in sc["views"].items():
            m = v["methods"]
            sec = {k: m[k].get("seconds") for k in ("vtk_fixed_1", "vtk_fixed_0.5", "pcvr", "regular") if k in m}
            fmt = lambda k: f"{sec[k]:.3f}" if sec.get(k) else "skipped"  # noqa: E731
            ratio = lambda a, b: f"{sec[a] / sec[b]:.2f}" if sec.get(a) and sec.get(b) else "-"  # noqa: E731
            db = lambda k: f"{m[k]['psnr_raycast']:.1f}" if "psnr_raycast" in m.get(k, {}) else "-"  # noqa: E731
            st = m["pcvr"]["stats"]
            stages = (f"{st['seconds_splat']:.2f} / {st.get('seconds_sampling', 0):.2f} / {st['seconds_post_convolution']:.2f} / "
                      f"{st['seconds_shading']:.2f}")
            lines.append(f"| {vk[1:]}^2 | {fmt('vtk_fixed_1')} | {fmt('vtk_fixed_0.5')} | {fmt('pcvr')} | {fmt('regular')} "
                         f"| {ratio('vtk_fixed_1', 'pcvr')} | {ratio('vtk_fixed_0.5', 'pcvr')} | {ratio('regular', 'pcvr')} "
                         f"| {db('vtk_fixed_1')} / {db('pcvr')} / {db('regular')} | {m['pcvr'].get('psnr_regular', float('nan')):.1f} "
                         f"| {stages} |")
        lines += ["", *cost_table(sc), ""]
    return lines


# Issue 20's aims: VTK step 1 time over `pcvr`'s, per image side; `regular`'s over `pcvr`'s at about four
# pixels a voxel (2048^2 here).
AIMS = {512: 1.0, 1024: 2.0, 2048: 3.0}
AIM_OVER_REGULAR, AIM_OVER_REGULAR_SIDE = 3.0, 2048
FILL_STAGES = ("seconds_splat", "seconds_sampling", "seconds_post_convolution")


def aims(res: dict) -> list[str]:
    """The aims against this run, and where the explanation of the misses is."""
    cells = []
    for tf_key, sc in res["scenes"].items():
        for vk, v in sc["views"].items():
            side = int(vk[1:])
            vtk, pcvr = v["methods"].get("vtk_fixed_1", {}).get("seconds"), v["methods"].get("pcvr", {}).get("seconds")
            if side in AIMS and vtk and pcvr:
                ratio = vtk / pcvr
                cells.append(f"{tf_key} {side}^2: {ratio:.2f} for {AIMS[side]:g} "
                             f"({'met' if ratio >= AIMS[side] else 'missed'})")
    if not cells:
        return []
    return ["Aims (VTK step 1 time over `pcvr`'s: no slower at 512^2, 2x at 1024^2, 3x at 2048^2): " + "; ".join(cells)
            + ". Where the time goes and what stands in the way, stage by stage: the cost-model tables below and "
            "docs/how-it-works.md, *Where the time goes: the cost model*.", "", *regular_bound(res)]


def regular_bound(res: dict) -> list[str]:
    """`regular` over `pcvr` at AIM_OVER_REGULAR_SIDE against its aim, beside the most it could be on this
    run: both methods shade the same samples, so with `pcvr`'s fill (splat or sampling, and post-convolution)
    free its time would still hold its shading and the rest."""
    cells = []
    for tf_key, sc in res["scenes"].items():
        m = sc["views"].get(f"p{AIM_OVER_REGULAR_SIDE}", {}).get("methods", {})
        if not (m.get("pcvr", {}).get("seconds") and m.get("regular", {}).get("seconds")):
            continue
        pcvr, regular = m["pcvr"]["seconds"], m["regular"]["seconds"]
        fill = sum(m["pcvr"]["stats"].get(k, 0.0) for k in FILL_STAGES) / res["threads"]
        cells.append(f"{tf_key} {regular / pcvr:.2f} (at most {regular / max(pcvr - fill, 1e-9):.2f} with a free fill)")
    if not cells:
        return []
    return [f"`regular` / `pcvr` at {AIM_OVER_REGULAR_SIDE}^2 (about four pixels a voxel; aim {AIM_OVER_REGULAR:g}): "
            + "; ".join(cells) + ". Both shade the same samples, so the shading bounds the ratio whatever the fill costs."]


def cost_table(sc: dict) -> list[str]:
    """Where the native methods' time goes, per unit of work (the cost model): thread-seconds of each
    stage (wall clock per stage, summed over the threads) over its counts."""
    lines = ["Cost model (the fastest run's `stats`): a *tap* is one subgrid node of a voxel's footprint window in "
             "one of the sheets its kernel reaches; a *sample* is one pixel's sample between two sheets that some "
             "voxel reaches while the pixel is not opaque (classified), and *shaded* the ones with extinction "
             "(gradient, lighting, compositing); a *sheet value* is one pixel's value of a sampled sheet, or one subgrid "
             "node's where the sheet is sampled at a stride and post-convolved (two trilinear reads of the prefiltered "
             "lattice), interpolated or, where no sample that may be visible reads it, skipped.", "",
             "| image | method | strides | deposits (M) | taps per deposit | splat ns per tap | sheet values interpolated / skipped (M) "
             "| sampling ns per interpolated value | samples classified / shaded (M) | shading ns per classified sample "
             "| post-convolution thread-s |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for vk, v in sc["views"].items():
        for key in NATIVE:
            st = v["methods"].get(key, {}).get("stats", {})
            if "taps" not in st:
                continue
            splat = (f"{st['taps'] / st['voxels']:.0f} | {1e9 * st['seconds_splat'] / st['taps']:.2f}" if st["voxels"] else "- | -")
            sampled = st.get("sheet_samples", 0)
            sampling = (f"{sampled / 1e6:.1f} / {st['sheet_samples_skipped'] / 1e6:.1f} | {1e9 * st['seconds_sampling'] / sampled:.1f}"
                        if sampled else "- | -")
            # Sampled sheets take their own subgrid strides (post-convolved above 1).
            subgrids = [s for s in st.get("sampled_strides", []) if s > 1]
            strides = ", ".join(map(str, st["strides"])) + (f" (sampled at {', '.join(map(str, subgrids))})" if subgrids else "")
            lines.append(f"| {vk[1:]}^2 | `{key}` | {strides} | {st['voxels'] / 1e6:.2f} "
                         f"| {splat} | {sampling} "
                         f"| {st['samples_classified'] / 1e6:.1f} / {st['samples_shaded'] / 1e6:.1f} "
                         f"| {1e9 * st['seconds_shading'] / max(st['samples_classified'], 1):.0f} "
                         f"| {st['seconds_post_convolution']:.2f} |")
    return lines


if __name__ == "__main__":
    import standalone
    standalone.main(__doc__, run, section)
