#!/usr/bin/env python3
"""DRRs beside plastimatch and RTK (issue 37): a real CT in Hounsfield units through one cone-beam geometry, by
PCVR, plastimatch `drr` (Siddon "exact" and "uniform" steps) and RTK's Joseph forward projector: time per DRR,
DRRs per second over a sweep, and error against a fine-step trilinear ray march.

| step      | what                                                                                            |
|-----------|-------------------------------------------------------------------------------------------------|
| volume    | ct_head_data's real CT head in Hounsfield units; mu = MU_WATER (1 + HU / 1000), never below 0,    |
|           | applied once: PCVR's grid through AttenuationMap.hounsfield(...).apply, the peers get the same mu |
|           | as an array (plastimatch `-P none`, so neither peer converts again)                              |
| geometry  | SAD 1000 mm, SID 1500 mm, a 614 mm square detector of 256^2, 512^2, 1024^2 pixels, isocentre the   |
|           | volume's centre, tilt 10 degrees, gantry 0, 30, 90, 150 (cone_beam_reference.geometry; PCVR     |
|           | through pcvr_native.cameras.cone_beam, the peers as drr_peers.py says)                          |
| check     | before timing, every method's full 128^2 image at each gantry angle against the reference: the  |
|           | detector shift and mirror of least mean absolute difference, and the scale (ratio of sums); a peer|
|           | whose shift passes half a pixel, mirrored or off in scale by 10% is not timed                    |
| reference | cone_beam_reference.march at 0.25 mm steps on one pixel in n each way (n odd, about 100^2 rays) |
| error     | relative RMSE over the sampled pixels: sqrt(mean((image - reference)^2)) / sqrt(mean(reference^2))|
| timing    | ROUNDS rounds over the views, the methods in an order rotated each time; the median per DRR, wall |
|           | and CPU seconds (drr_peers.py says whose)                                                         |
|           | Sweep: SWEEP_VIEWS gantry angles round a circular orbit (tilt 0) of one prepared volume: PCVR in |
|           | a loop over cameras, plastimatch in one process (`-a`), RTK in one projection stack              |
| threads   | 2 for all: PCVR threads=2, plastimatch OMP_NUM_THREADS=2, ITK's global default threads 2          |

    python tests/bench/drr_bench.py [--quick]      # prints the section; --quick: 256^2, gantry 30, one round
"""

from __future__ import annotations

import dataclasses
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.append(str(HERE))
sys.path.append(str(HERE.parent))

import ct_head_data  # noqa: E402
import drr_peers  # noqa: E402
from cone_beam_reference import geometry as cone_beam_geometry, march  # noqa: E402

MU_WATER_PER_MM = 0.0193          # the add-on's default, 0.193 per cm
SAD_MM, SID_MM, DETECTOR_MM, TILT_DEG = 1000.0, 1500.0, 614.0, 10.0
SIZES, QUICK_SIZES = (256, 512, 1024), (256,)
GANTRIES, QUICK_GANTRIES = (0.0, 30.0, 90.0, 150.0), (30.0,)
SWEEP_VIEWS, QUICK_SWEEP_VIEWS = 8, 4
ROUNDS, QUICK_ROUNDS = 3, 1
SLOW_S = 5.0                      # a method slower than this per DRR renders each view once
THREADS = 2
REFERENCE_STEP_MM = 0.25
REFERENCE_RAYS = 100              # sampled pixels per side, about
CHECK_SIZE = 128                  # the geometry check's detector, marched whole
CHECK_REACH = 2                   # shifts tried by the check, pixels each way
METHODS = ("pcvr", "plastimatch exact", "plastimatch uniform", "rtk joseph")
PCVR_STATS = ("magnification", "magnification_max", "stride", "level", "supersampling", "voxels")
LABELS = {"pcvr": "PCVR (defaults)", "plastimatch exact": "plastimatch exact (Siddon)",
          "plastimatch uniform": "plastimatch uniform", "rtk joseph": "RTK Joseph"}


@dataclasses.dataclass(frozen=True)
class View:
    """One radiograph's set-up: the cone-beam parameters and the reference's geometry built from them."""
    size: int
    gantry: float
    tilt: float
    isocentre: tuple

    @property
    def pixel_mm(self) -> float:
        return DETECTOR_MM / self.size

    def parameters(self) -> dict:
        return {"sad": SAD_MM, "sid": SID_MM, "detector": (self.size, self.size),
                "pixel_spacing": (self.pixel_mm, self.pixel_mm), "isocentre": self.isocentre,
                "gantry": self.gantry, "tilt": self.tilt}

    def geometry(self):
        return cone_beam_geometry(**self.parameters())

    def camera(self):
        from pcvr_native.cameras import cone_beam
        return cone_beam(**self.parameters())


def sampled_geometry(geom, step: int):
    """The reference's geometry of every `step`-th pixel from pixel step // 2 on (a coarser detector whose pixel
    centres are those pixels), and the slice that picks them from a full image."""
    cols, rows = geom.detector
    du, dv = geom.pixel_spacing
    first = step // 2
    count_c, count_r = len(range(first, cols, step)), len(range(first, rows, step))
    # Centre of the first picked pixel, on the full detector and on the coarse one: the offset between them.
    shift_u = (first + 0.5 - cols / 2.0) * du - (0.5 - count_c / 2.0) * step * du
    shift_v = -((first + 0.5 - rows / 2.0) * dv - (0.5 - count_r / 2.0) * step * dv)
    coarse = dataclasses.replace(geom, detector=(count_c, count_r), pixel_spacing=(step * du, step * dv),
                                 detector_centre=geom.detector_centre + shift_u * geom.right + shift_v * geom.up)
    return coarse, (slice(first, None, step), slice(first, None, step))


def reference(mu, index_to_world, view: View, step: int) -> np.ndarray:
    spacing = float(np.linalg.norm(np.asarray(index_to_world)[:3, :3], axis=0).min())
    geom, _ = sampled_geometry(view.geometry(), step)
    return march(mu, index_to_world, geom, samples_per_voxel=spacing / REFERENCE_STEP_MM)


def relative_rmse(image, reference_image) -> float:
    ref = np.asarray(reference_image, dtype=np.float64)
    return float(np.sqrt(np.mean((np.asarray(image, dtype=np.float64) - ref) ** 2)) / np.sqrt(np.mean(ref ** 2)))


FLIPS = {"none": (1, 1), "left-right": (1, -1), "up-down": (-1, 1), "both": (-1, -1)}


def alignment(image, reference_image, reach: int = CHECK_REACH) -> dict:
    """How a method's full image lines up with the reference's: the scale, the ratio of their sums (1 where both
    integrate the same mu in the same units; a shift or mirror leaves it); then, the scale divided out, the mirror and the shift of
    the image's content against the reference's (pixels right, down; sub-pixel by a parabola through the least
    mean absolute difference and its neighbours) that best align them; and that difference relative to the
    reference's mean, aligned and as rendered (neither scaled nor moved)."""
    image = np.asarray(image, dtype=np.float64)
    ref = np.asarray(reference_image, dtype=np.float64)
    scale = float(image.sum() / ref.sum())
    rows, cols = ref.shape
    inner = ref[reach:rows - reach, reach:cols - reach]
    span = range(-reach, reach + 1)
    tables = {}
    for name, (flip_r, flip_c) in FLIPS.items():
        flipped = image[::flip_r, ::flip_c] / (scale if scale > 0 else 1.0)
        tables[name] = np.array([[np.abs(flipped[reach + dr:rows - reach + dr, reach + dc:cols - reach + dc] - inner).mean()
                                  for dc in span] for dr in span])
    flip = min(tables, key=lambda name: tables[name].min())
    table = tables[flip]
    r, c = np.unravel_index(np.argmin(table), table.shape)

    def vertex(left, mid, right):
        curve = left - 2 * mid + right
        return 0.5 * (left - right) / curve if curve > 0 else 0.0

    sub_r = vertex(table[r - 1, c], table[r, c], table[r + 1, c]) if 0 < r < 2 * reach else 0.0
    sub_c = vertex(table[r, c - 1], table[r, c], table[r, c + 1]) if 0 < c < 2 * reach else 0.0
    mean = inner.mean()
    as_rendered = np.abs(image[reach:rows - reach, reach:cols - reach] - inner).mean()
    return {"flip": flip, "shift_px": [float(c - reach + sub_c), float(r - reach + sub_r)],
            "mad_aligned": float(table.min() / mean), "mad_as_rendered": float(as_rendered / mean), "scale": scale}


def geometry_agrees(check: dict) -> str | None:
    """None where the alignment says the method's geometry is the reference's, else why not."""
    if check["flip"] != "none":
        return f"mirrored ({check['flip']})"
    if max(abs(s) for s in check["shift_px"]) > 0.5:
        return f"shifted by {check['shift_px'][0]:+.2f}, {check['shift_px'][1]:+.2f} pixels"
    if abs(check["scale"] - 1.0) > 0.1:
        return f"scaled by {check['scale']:.3f}"
    return None


def load_volume(log):
    """(HU values [i, j, k], index_to_world, description), or raise ct_head_data.Unavailable."""
    values, index_to_world, meta = ct_head_data.load()
    log(f"drr: {meta['source']}, {' x '.join(map(str, values.shape))}")
    return values, np.asarray(index_to_world, dtype=np.float64), meta


def make_renderers(hu, index_to_world, workdir: Path, log):
    """({method: render(view) -> (image, seconds, CPU seconds)}, {"plastimatch" / "rtk": the peer}, {method: version or why it
    is missing}, mu): every method integrates the same mu, PCVR's grid mapped once (as the add-on keeps it), the
    peers the mapped array."""
    import pcvr_native as pn
    mapped = pn.AttenuationMap.hounsfield(MU_WATER_PER_MM).apply(
        pn.Grid.from_dense(hu, index_to_world, background=ct_head_data.AIR_HU))
    mu = np.maximum(MU_WATER_PER_MM * (1.0 + hu / 1000.0), 0.0).astype(np.float32)

    def pcvr(view: View):
        stats: dict = {}
        cpu0, t0 = drr_peers.cpu_seconds(), time.perf_counter()
        image = pn.render_xray(mapped, view.camera(), threads=THREADS, stats=stats)
        seconds, cpu = time.perf_counter() - t0, drr_peers.cpu_seconds() - cpu0
        pcvr.stats = {k: stats.get(k) for k in PCVR_STATS}   # what the last render chose
        return image, seconds, cpu

    renderers, peers = {"pcvr": pcvr}, {}
    versions = {"pcvr": pcvr_version()}
    try:
        plastimatch = peers["plastimatch"] = drr_peers.Plastimatch(mu, index_to_world, THREADS, workdir)
        versions["plastimatch exact"] = versions["plastimatch uniform"] = plastimatch.version()
        for algorithm in ("exact", "uniform"):
            renderers[f"plastimatch {algorithm}"] = (
                lambda view, a=algorithm: plastimatch.render(a, view.geometry(), view.isocentre))
    except drr_peers.PeerUnavailable as e:
        log(f"drr: {e}")
        versions["plastimatch exact"] = versions["plastimatch uniform"] = f"missing: {e}"
    try:
        rtk = peers["rtk"] = drr_peers.RtkJoseph(mu, index_to_world, THREADS, volume_centre(hu.shape, index_to_world))
        versions["rtk joseph"] = rtk.version()
        renderers["rtk joseph"] = lambda view: rtk.render(view.geometry())
    except drr_peers.PeerUnavailable as e:
        log(f"drr: {e}")
        versions["rtk joseph"] = f"missing: {e}"
    return renderers, peers, versions, mu


def pcvr_version() -> str:
    """The native module's version and the commit of the checkout that runs the bench (whose build it should be)."""
    from importlib.metadata import PackageNotFoundError, version
    try:
        built = version("pcvr_native")
    except PackageNotFoundError:
        built = "?"
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=HERE, capture_output=True, text=True)
    return f"pcvr_native {built}, checkout {commit.stdout.strip() or '?'}"


def volume_centre(shape, index_to_world) -> tuple:
    centre = (np.asarray(shape, dtype=np.float64) - 1.0) / 2.0
    return tuple(float(x) for x in np.asarray(index_to_world)[:3, :3] @ centre + np.asarray(index_to_world)[:3, 3])


def check_geometry(renderers, mu, index_to_world, isocentre, gantries, log) -> dict:
    """{method: {"views": [alignment per gantry], "failed": reason or None}} on full CHECK_SIZE^2 images."""
    out = {m: {"views": [], "failed": None} for m in METHODS if m in renderers}
    for gantry in gantries:
        view = View(CHECK_SIZE, gantry, TILT_DEG, isocentre)
        ref = reference(mu, index_to_world, view, 1)
        for method in out:
            image = renderers[method](view)[0]
            check = alignment(image, ref)
            out[method]["views"].append({"gantry": gantry, **check})
            out[method]["failed"] = out[method]["failed"] or geometry_agrees(check)
    for method, rec in out.items():
        worst = max(max(abs(s) for s in v["shift_px"]) for v in rec["views"])
        log(f"  drr geometry {method}: worst shift {worst:.2f} px, scale "
            f"{min(v['scale'] for v in rec['views']):.3f}-{max(v['scale'] for v in rec['views']):.3f}"
            + (f", FAILED: {rec['failed']}" if rec["failed"] else ""))
    return out


def time_views(renderers, methods, views, references, step, rounds) -> dict:
    """{method: {"seconds": [...], "cpu": [...], "errors": [per view]}}: rounds over the views, methods in rotated
    order."""
    out = {m: {"seconds": [], "cpu": [], "errors": [None] * len(views)} for m in methods}
    slow = set()
    for r in range(rounds):
        for v, view in enumerate(views):
            order = methods[r % len(methods):] + methods[:r % len(methods)]
            for method in order:
                if r > 0 and method in slow:
                    continue
                image, seconds, cpu = renderers[method](view)
                out[method]["seconds"].append(seconds)
                out[method]["cpu"].append(cpu)
                if seconds > SLOW_S:
                    slow.add(method)
                if out[method]["errors"][v] is None:
                    sl = sampled_geometry(view.geometry(), step)[1]
                    out[method]["errors"][v] = relative_rmse(np.asarray(image)[sl], references[v])
    return out


def sweep(renderers, peers, methods, size, isocentre, count) -> dict:
    """{method: {"drrs_per_s", "seconds", "agreement"}}: `count` views round a circular orbit (tilt 0); agreement is
    each peer's images against PCVR's at the same angles (relative RMSE), which catches a wrong angle order."""
    gantries = [360.0 * i / count for i in range(count)]
    views = [View(size, g, 0.0, isocentre) for g in gantries]
    out, images = {}, {}
    if "pcvr" in methods:
        t0 = time.perf_counter()
        images["pcvr"] = [renderers["pcvr"](view)[0] for view in views]
        out["pcvr"] = {"seconds": time.perf_counter() - t0}
    for algorithm in ("exact", "uniform"):
        if f"plastimatch {algorithm}" in methods:
            images[f"plastimatch {algorithm}"], seconds, wall = peers["plastimatch"].sweep(
                algorithm, views[0].geometry(), isocentre, gantries)
            out[f"plastimatch {algorithm}"] = {"seconds": seconds, "wall_with_loading": wall}
    if "rtk joseph" in methods:
        images["rtk joseph"], seconds = peers["rtk"].sweep([view.geometry() for view in views])
        out["rtk joseph"] = {"seconds": seconds}
    for method, rec in out.items():
        rec["drrs_per_s"] = count / rec["seconds"]
        if method != "pcvr" and "pcvr" in images:
            rec["agreement"] = max(relative_rmse(a, b) for a, b in zip(images[method], images["pcvr"]))
    return out


def run(quick: bool, log) -> dict:
    try:
        hu, index_to_world, meta = load_volume(log)
    except ct_head_data.Unavailable as e:
        log(f"drr: the CT head is unavailable ({e})")
        return {"error": f"the CT head is unavailable: {e}"}
    sizes, gantries = (QUICK_SIZES, QUICK_GANTRIES) if quick else (SIZES, GANTRIES)
    rounds, sweep_views = (QUICK_ROUNDS, QUICK_SWEEP_VIEWS) if quick else (ROUNDS, SWEEP_VIEWS)
    isocentre = volume_centre(hu.shape, index_to_world)
    out = {"source": meta["source"], "shape": list(hu.shape), "spacing": meta["spacing"], "threads": THREADS,
           "mu_water_per_mm": MU_WATER_PER_MM, "sad": SAD_MM, "sid": SID_MM, "detector_mm": DETECTOR_MM,
           "tilt": TILT_DEG, "gantries": list(gantries), "sweep_views": sweep_views, "rounds": rounds,
           "load_before": os.getloadavg(), "sizes": {}}
    with tempfile.TemporaryDirectory(prefix="drr-bench-") as tmp:
        renderers, peers, out["versions"], mu = make_renderers(hu, index_to_world, Path(tmp), log)
        if "plastimatch" in peers:
            out["plastimatch_load_cpu_s"] = peers["plastimatch"].load_cpu
        out["check"] = check_geometry(renderers, mu, index_to_world, isocentre, gantries, log)
        methods = [m for m in METHODS if m in out["check"] and not out["check"][m]["failed"]]
        for size in sizes:
            views = [View(size, g, TILT_DEG, isocentre) for g in gantries]
            step = max(1, size // REFERENCE_RAYS) | 1  # odd: the sampled pixels' centres are pixel centres
            t0 = time.perf_counter()
            references = [reference(mu, index_to_world, view, step) for view in views]
            log(f"  drr {size}^2: references ({references[0].shape[0]}^2 rays each) in {time.perf_counter() - t0:.1f} s")
            timing = time_views(renderers, methods, views, references, step, rounds)
            pcvr_stats = getattr(renderers["pcvr"], "stats", None)
            swept = sweep(renderers, peers, methods, size, isocentre, sweep_views)
            rec = out["sizes"][str(size)] = {"reference_step": step, "methods": {}, "pcvr_stats": pcvr_stats}
            for method in methods:
                seconds = timing[method]["seconds"]
                rec["methods"][method] = {"median_s": statistics.median(seconds), "renders": len(seconds),
                                          "median_cpu_s": statistics.median(timing[method]["cpu"]),
                                          "errors": timing[method]["errors"], **swept.get(method, {})}
            log(f"  drr {size}^2: " + ", ".join(
                f"{m} {r['median_s']:.3f} s ({statistics.mean(r['errors']):.2%}, {r['drrs_per_s']:.2f}/s)"
                for m, r in rec["methods"].items()))
    out["load_after"] = os.getloadavg()
    return out


def _ms(seconds: float) -> str:
    return f"{seconds * 1000:,.0f} ms" if seconds < 10 else f"{seconds:,.1f} s"


def section(res: dict | None) -> list[str]:
    title = "## DRRs beside plastimatch and RTK"
    if not res or "error" in res:
        return [title, "", f"Not measured: {res['error']}.", ""] if res else []
    lines = [title, ""]
    gantries = ", ".join(f"{g:g}" for g in res["gantries"])
    lines += [
        f"Volume: {res['source']} ({' x '.join(map(str, res['shape']))} voxels of "
        f"{' x '.join(f'{s:.3g}' for s in res['spacing'])} mm), in attenuation mu = {res['mu_water_per_mm']} / mm "
        f"(1 + HU / 1000), never below 0, mapped once for everyone. Cone beam: SAD {res['sad']:g} mm, SID {res['sid']:g} mm, "
        f"a {res['detector_mm']:g} mm square detector, isocentre the volume's centre, tilt {res['tilt']:g} degrees, gantry "
        f"{gantries}. {res['threads']} threads each. *s per DRR*: the median over those views and {res['rounds']} "
        f"alternating round(s) (slow methods once per view); plastimatch's own render time (its total less "
        f"writing images, without loading the volume), RTK's projector update. *CPU s*: user and system seconds of all "
        f"threads in the same renders (plastimatch's process less one that loads the volume and draws a pixel), the "
        f"work done whatever else the machine runs, busy-waiting threads included. *DRRs/s*: a sweep of "
        f"{res['sweep_views']} views round a circular orbit (tilt 0) of one prepared volume. *Error*: relative RMSE "
        f"against `tests/cone_beam_reference.py`'s trilinear ray march at 0.25 mm steps on every n-th pixel, mean over "
        f"the gantry angles (worst). Load average {res['load_before'][0]:.1f} before, {res['load_after'][0]:.1f} after "
        f"(`tests/bench/drr_bench.py`).", ""]
    for size, rec in res["sizes"].items():
        methods = rec["methods"]
        exact = methods.get("plastimatch exact")
        lines += [f"### {size} x {size} (reference: one pixel in {rec['reference_step']} each way)", "",
                  "| method | s per DRR | CPU s per DRR | DRRs/s (sweep) | error vs reference | plastimatch exact time / this |",
                  "|---|---|---|---|---|---|"]
        for method, r in methods.items():
            ratio = f"{exact['median_s'] / r['median_s']:.1f}" if exact else "-"
            lines.append(f"| {LABELS[method]} | {_ms(r['median_s'])} | {_ms(r['median_cpu_s'])} | {r['drrs_per_s']:.2f} | "
                         f"{statistics.mean(r['errors']):.2%} ({max(r['errors']):.2%}) | {ratio} |")
        pcvr = methods.get("pcvr")
        if pcvr and exact:
            speed = exact["median_s"] / pcvr["median_s"]
            lower = statistics.mean(pcvr["errors"]) < statistics.mean(exact["errors"])
            lines += ["", f"PCVR is {speed:.1f}x plastimatch exact's speed (aim: 5x) at "
                      f"{'lower' if lower else 'higher'} error ({statistics.mean(pcvr['errors']):.2%} against "
                      f"{statistics.mean(exact['errors']):.2%})."]
        st = rec.get("pcvr_stats")
        if st:
            lines += ["", f"PCVR chose: {st['magnification']:.2f}-{st['magnification_max']:.2f} pixels per voxel, "
                      f"subgrid stride {st['stride']:.2f}, level {st['level']}, supersampling {st['supersampling']}, "
                      f"{st['voxels']:,} voxels splatted."]
        lines.append("")
    lines += ["### Geometry agreement", "",
              f"Each method's full {CHECK_SIZE} x {CHECK_SIZE} image at every gantry angle against the reference's: "
              "the detector shift of least mean absolute difference (columns, rows; in pixels of "
              f"{DETECTOR_MM / CHECK_SIZE:.2f} mm, worst over the angles), no mirror, that difference relative to the "
              "reference's mean as rendered and aligned, and the scale, the ratio of the image's sum to the reference's "
              "(1: the same mu integrated in the same units). Versions: "
              + "; ".join(f"{LABELS[m]}: {v}" for m, v in res["versions"].items()) + ".", "",
              "| method | worst shift (px) | mirror | difference as rendered | aligned, scale divided out | scale | timed |",
              "|---|---|---|---|---|---|---|"]
    for method, rec in res["check"].items():
        views = rec["views"]
        worst = max(views, key=lambda v: max(abs(s) for s in v["shift_px"]))
        mirrors = sorted({v["flip"] for v in views})
        lines.append(f"| {LABELS[method]} | {worst['shift_px'][0]:+.2f}, {worst['shift_px'][1]:+.2f} | "
                     f"{', '.join(mirrors)} | {max(v['mad_as_rendered'] for v in views):.2%} | "
                     f"{max(v['mad_aligned'] for v in views):.2%} | "
                     f"{min(v['scale'] for v in views):.3f}-{max(v['scale'] for v in views):.3f} | "
                     f"{'no: ' + rec['failed'] if rec['failed'] else 'yes'} |")
    sweeps = [(size, m, r["agreement"]) for size, rec in res["sizes"].items() for m, r in rec["methods"].items()
              if "agreement" in r]
    if sweeps:
        lines += ["", "Sweeps: each peer's images against PCVR's at the same angles, worst relative RMSE: "
                  + ", ".join(f"{LABELS[m]} {a:.2%} ({s}^2)" for s, m, a in sweeps) + "."]
    loading = [(size, m, r["wall_with_loading"]) for size, rec in res["sizes"].items()
               for m, r in rec["methods"].items() if "wall_with_loading" in r]
    if loading:
        lines += ["", f"plastimatch's whole sweep process ({res['sweep_views']} DRRs), loading the volume and writing the "
                  "images included: " + ", ".join(f"{LABELS[m]} {w:.1f} s ({s}^2)" for s, m, w in loading) + "."]
    return lines + [""]


if __name__ == "__main__":
    import standalone
    standalone.main(__doc__, run, section)
