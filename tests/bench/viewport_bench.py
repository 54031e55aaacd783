#!/usr/bin/env python3
"""The rendered viewport's speed: the CT phantom in a 1280 x 720 region, X-ray and shaded, through the add-on's
own viewport path (prepared_scene.prepare, native_render.render_viewport_step, passes.viewport_pixels, and the
viewport.ProgressiveRenderer that schedules them on its worker thread), without Blender's window.

| measurement | what                                                                                       |
|-------------|--------------------------------------------------------------------------------------------|
| steps       | each step of viewport.STEPS rendered and finished from ORBIT_VIEWS views around the phantom:  |
|             | median milliseconds and images per second                                                  |
| latency     | the renderer moved to each of those views in turn, waiting in between until it is idle: time |
|             | from the change to the first image of the new view, and to its full-resolution image (medians; |
|             | the first view, before any timing is known, left out)                                      |
| motion      | the view moved 60 times a second for MOTION_SECONDS: images shown per second while moving   |
| at 256^3    | shaded full-resolution images of the 256^3 phantom (AIM_N), with RAMP and with the skull     |
|             | alone (SKULL_RAMP): median milliseconds over the views, against AIM_FULL_SHADED_MS           |
| clinical    | issue 36's aim: shaded full-resolution images of a clinical-size CT head (the InVesalius head |
|             | upsampled to CLINICAL_SHAPE, ct_head.py's transfer functions) on CLINICAL_THREADS threads once |
|             | the scene is prepared: median milliseconds and each stage's (stats seconds_*), against       |
|             | AIM_CLINICAL_MS; skipped, saying why, where the head cannot be fetched                       |

    python tests/bench/viewport_bench.py [--quick] [--modes SHADED] [--clinical-only]     # prints the tables

The renderer's steps render at 1/8, 1/4, 1/2 and full resolution (shaded also with 4 and 2 times the sheet
spacing at 1/8 and 1/4, and below full resolution from the coarsest level of detail whose voxels project to at
most a pixel of the step's image: viewport.step_level); it starts a change with the finest step measured to take
at most 50 ms.
"""

from __future__ import annotations

import argparse
import datetime
import math
import os
import statistics
import sys
import threading
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
sys.path.insert(0, str(REPO))

REGION = (1280, 720)
ORBIT_VIEWS = 12
MOTION_SECONDS = 3.0
MOTION_HZ = 60.0
AIM_FIRST_MS = 50.0
AIM_REFINED_XRAY_MS = 100.0
# A CT-like transfer function over the phantom's 0..1: soft tissue faint and warm, bone white and dense; lit by
# one sun from the upper left, as the shaded defaults of the command line are.
RAMP = ((0.0, (0.0, 0.0, 0.0, 0.0)), (0.25, (0.8, 0.5, 0.4, 0.02)), (0.6, (0.9, 0.85, 0.8, 0.3)),
        (1.0, (1.0, 1.0, 1.0, 0.9)))
# The skull alone: what a bone preset shows (rays stop at the skull; the brain is clear).
SKULL_RAMP = ((0.0, (0.0, 0.0, 0.0, 0.0)), (0.6, (0.9, 0.85, 0.8, 0.0)), (1.0, (1.0, 1.0, 1.0, 0.9)))
SUN_DIRECTION = (0.4, -0.4, -0.8)
# Issue 20's aim: a full-resolution shaded 1280 x 720 image of a 256^3 CT within 100 ms.
AIM_N, AIM_FULL_SHADED_MS = 256, 100.0
# Issue 36's aim: a full-resolution shaded 1280 x 720 redraw of a clinical-size CT head (about 512 x 512 x 250)
# within 100 ms on two threads once the scene is prepared. No public CT of that size could be fetched here
# (shaded_volumes.py), so the InVesalius head (256 x 256 x 108) is upsampled to it, its spacing shrunk to keep
# its size in millimetres.
CLINICAL_SHAPE, CLINICAL_THREADS, AIM_CLINICAL_MS = (512, 512, 250), 2, 100.0
CLINICAL_VIEWS, QUICK_CLINICAL_VIEWS = 6, 3
# The native render's wall seconds and the stages it reports (stats; plan and shadows in wall seconds, the others
# summed over the threads), in the order they run.
STAGE_SECONDS = ("seconds", "seconds_plan", "seconds_shadows", "seconds_sampling", "seconds_splat", "seconds_post_convolution",
                 "seconds_shading")


def phantom_grid(n):
    from pcvr_native import phantoms
    phantom = phantoms.ct_phantom(n)
    return phantom.grid(), phantom.index_to_world


def inputs_for(mode, grid, points=RAMP, tf_range=(0.0, 1.0), opacity_scale=1.0, threads=0, name="CT phantom"):
    """RenderInputs and DisplayInputs of a grid (the phantom's by default), as scene_inputs.read makes them from a
    Blender scene: `points` over the densities `tf_range`, opacity per voxel over `opacity_scale`."""
    from pcvr_addon.scene import lighting, scene_inputs as si

    ramp = si.RampInputs(positions=tuple(p for p, _ in points), rgba=tuple(c for _, c in points), use_grid_range=False,
                         tf_min=tf_range[0], tf_max=tf_range[1], opacity_scale=opacity_scale)
    volume = si.VolumeInputs(name=name, filepath="", grid_name=None,
                             object_to_world=tuple(map(tuple, np.eye(4))), density_scale=1.0,
                             ramp=ramp if mode == 'SHADED' else None,
                             # scene_inputs.material's tuple: shaded, Blinn-Phong 0.1 / 0.9 / 0.2 / 10, no ambient occlusion,
                             # (scattering octaves unused)
                             material=si.Material(True, 0.1, 0.9, 0.2, 10.0, None, False, 6) if mode == 'SHADED' else None,
                             grid=grid)
    world = (0.05, 0.05, 0.05)
    sun = lighting.LightSpec("sun", SUN_DIRECTION, (1.0, 1.0, 1.0), 1.0)
    settings = dict(method="pcvr", splat_kernel="gauss1.4", stride=0)
    from pcvr_addon.scene import defaults
    inputs = si.RenderInputs(
        mode=mode, volumes=(volume,), threads=threads,
        xray=si.XRaySettings(post_filter=defaults.XRAY["post_filter"], passband=defaults.XRAY["passband"], **settings)
        if mode == 'XRAY' else None,
        sheets=si.SheetSettings(post_filter=defaults.SHEETS["post_filter"],
                                sheet_spacing=defaults.SHEETS["sheet_spacing"],
                                samples_per_sheet=defaults.SHEETS["samples_per_sheet"],
                                opacity_cutoff=defaults.SHEETS["opacity_cutoff"], **settings)
        if mode != 'XRAY' else None,
        lights=(sun,) if mode == 'SHADED' else (), world=world if mode == 'SHADED' else (0.0, 0.0, 0.0))
    display = si.DisplayInputs(mode=mode, film_transparent=False, world=world if mode != 'XRAY' else (0, 0, 0))
    return inputs, display


def orbit(index_to_world, shape, count):
    """`count` perspective views at 1280 x 720 around the centre of a grid's index box 0 .. `shape` - 1, filling
    about 80% of the height."""
    from pcvr_addon.scene.camera import CameraView
    from pcvr_native.cameras import look_at, perspective

    centre = (np.asarray(index_to_world) @ np.array([(n - 1) / 2 for n in shape] + [1.0]))[:3]
    radius = np.linalg.norm(np.asarray(index_to_world)[:3, :3] @ (np.asarray(shape) / 2))
    fov = math.radians(40.0)
    distance = radius / math.sin(fov / 2) / 0.8
    views = []
    for k in range(count):
        angle = 2 * math.pi * k / count
        eye = centre + distance * np.array([math.cos(angle) * 0.9, math.sin(angle) * 0.9, 0.44])
        views.append(CameraView(look_at(eye, centre), perspective(fov, REGION[0] / REGION[1], 0.1 * distance,
                                                                  10 * distance), *REGION))
    return views


def time_step(prepared, display, views, step, stats=None):
    """Seconds of one viewport step (render and finish) from each of `views`; each render's stats appended to
    the list `stats` where given."""
    from pcvr_addon.render import native_render, passes

    never = threading.Event()
    seconds = []
    for view in views:
        view_stats = {}
        start = time.perf_counter()
        raw = native_render.render_viewport_step(prepared, view, step, never, stats=view_stats)
        passes.viewport_pixels(display, raw)
        seconds.append(time.perf_counter() - start)
        if stats is not None:
            stats.append(view_stats)
    return seconds


def time_steps(prepared, display, views):
    """Median seconds of each viewport step (render and finish) over `views`."""
    from pcvr_addon.render import native_render, viewport

    rows = []
    for step in viewport.STEPS:
        seconds = time_step(prepared, display, views, step)
        scaled = views[0].scaled(step.scale)
        level = native_render.viewport_step_level(prepared, views[0], step)
        rows.append({"scale": step.scale, "sheet_spacing": step.sheet_spacing, "level": level, "width": scaled.width,
                     "height": scaled.height, "median_s": statistics.median(seconds), "min_s": min(seconds)})
    return rows


class Watcher:
    """A ProgressiveRenderer with an event per new image."""

    def __init__(self, inputs, display):
        from pcvr_addon.render import native_render, passes, prepared_scene, viewport
        self.new_image = threading.Event()
        self.renderer = viewport.ProgressiveRenderer(prepared_scene.prepare, native_render.render_viewport_step,
                                                     passes.viewport_pixels, on_image=self.new_image.set,
                                                     cost_key=lambda i: i.mode)
        self.renderer.update_scene(inputs, display)

    def first_image_of(self, view, timeout=60.0):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            image = self.renderer.latest()
            if image is not None and image.view == view:
                return image
            self.new_image.wait(0.001)
            self.new_image.clear()
        raise TimeoutError("no image of the new view")


def latency(inputs, display, views):
    """Seconds from a view change to its first image and to its full-resolution image (medians, the first view
    left out), and the step the first image came from."""
    watcher = Watcher(inputs, display)
    first, full, first_scales = [], [], []
    try:
        for view in views:
            start = time.perf_counter()
            watcher.renderer.update_view(view)
            image = watcher.first_image_of(view)
            first.append(time.perf_counter() - start)
            first_scales.append(image.step.scale)
            watcher.renderer.wait_until_idle(120.0)
            full.append(time.perf_counter() - start)
    finally:
        watcher.renderer.stop()
    return {"first_s": statistics.median(first[1:]), "full_s": statistics.median(full[1:]),
            "first_scale": statistics.mode(first_scales[1:])}


def motion(inputs, display, views, seconds=MOTION_SECONDS, hz=MOTION_HZ):
    """Images shown per second while the view changes `hz` times a second (going round `views`)."""
    watcher = Watcher(inputs, display)
    watcher.renderer.update_view(views[0])
    watcher.first_image_of(views[0])
    watcher.renderer.wait_until_idle(120.0)       # timings known, as after a moment of use
    serial = watcher.renderer.latest().serial
    start = time.perf_counter()
    k = 0
    try:
        while (elapsed := time.perf_counter() - start) < seconds:
            watcher.renderer.update_view(views[k % len(views)])
            k += 1
            time.sleep(max(0.0, k / hz - elapsed))
        shown = watcher.renderer.latest().serial - serial
        cancelled = watcher.renderer.counts["cancelled"]
    finally:
        watcher.renderer.stop()
    return {"images_per_s": shown / seconds, "changes": k, "cancelled": cancelled}


def full_resolution_at(n, view_count, log):
    """Shaded full-resolution viewport images of the n^3 phantom with RAMP and SKULL_RAMP: median and least
    milliseconds over `view_count` views, after a first render from each (which builds what a grid keeps:
    its prefiltered lattice, its value ranges)."""
    from pcvr_addon.render import prepared_scene, viewport

    grid, index_to_world = phantom_grid(n)
    views = orbit(index_to_world, (n, n, n), view_count)
    out = {"n": n, "active_voxels": grid.active_voxel_count, "ramps": {}}
    for name, points in (("ramp", RAMP), ("skull", SKULL_RAMP)):
        log(f"viewport SHADED {n}^3 ({name}): full resolution")
        inputs, display = inputs_for('SHADED', grid, points)
        prepared = prepared_scene.prepare(inputs)
        time_step(prepared, display, views, viewport.STEPS[-1])
        seconds = time_step(prepared, display, views, viewport.STEPS[-1])
        out["ramps"][name] = {"median_s": statistics.median(seconds), "min_s": min(seconds)}
    return out


def upsampled(values, shape):
    """`values` resampled to `shape` by linear interpolation along each axis in turn, the box's corner voxels
    kept where they were."""
    for axis, n in enumerate(shape):
        old = values.shape[axis]
        x = np.linspace(0.0, old - 1.0, n)
        below = np.minimum(np.floor(x).astype(np.intp), old - 2)
        fraction = (x - below).astype(np.float32).reshape([n if a == axis else 1 for a in range(3)])
        first, second = np.take(values, below, axis=axis), np.take(values, below + 1, axis=axis)
        values = first + (second - first) * fraction
    return np.ascontiguousarray(values, dtype=np.float32)


def clinical_head():
    """(pcvr_native.Grid, shape, index_to_world) of the InVesalius head upsampled to CLINICAL_SHAPE (air at
    ct_head_data.AIR_HU inactive). Raises ct_head_data.Unavailable where the head cannot be fetched."""
    import ct_head_data
    import pcvr_native

    values, index_to_world, _meta = ct_head_data.load()
    fine = upsampled(values, CLINICAL_SHAPE)
    fine_to_coarse = np.diag([(old - 1) / (new - 1) for old, new in zip(values.shape, CLINICAL_SHAPE)] + [1.0])
    to_world = np.asarray(index_to_world) @ fine_to_coarse
    return pcvr_native.Grid.from_dense(fine, to_world, background=ct_head_data.AIR_HU), CLINICAL_SHAPE, to_world


def ramp_of(transfer_function, voxel):
    """(ramp points, tf_range, opacity_scale) for inputs_for of one of ct_head.TRANSFER_FUNCTIONS (Hounsfield
    units, opacity per unit_distance) on a grid of smallest spacing `voxel`."""
    density = np.asarray(transfer_function["density"], dtype=np.float64)
    low, high = float(density[0]), float(density[-1])
    points = tuple((float((d - low) / (high - low)), tuple(rgba)) for d, rgba in zip(density, transfer_function["rgba"]))
    return points, (low, high), voxel / transfer_function["unit_distance"]


def stage_medians(stats):
    """Each stage's median seconds (STAGE_SECONDS) and the sampled share over a list of render stats."""
    out = {key: statistics.median(s.get(key, 0.0) for s in stats) for key in STAGE_SECONDS}
    for key in ("samples_classified", "samples_shaded", "sheet_samples", "grids_sampled"):
        out[key] = statistics.median(s.get(key, 0) for s in stats)
    return out


def clinical(view_count, log):
    """Issue 36's viewport aim: the clinical-size head at full resolution on CLINICAL_THREADS threads with each
    of ct_head's transfer functions, after the scene is prepared and one render (which builds what the grid
    keeps) has run: median and least milliseconds over `view_count` views, and each stage's median."""
    import ct_head
    import ct_head_data
    from pcvr_addon.render import prepared_scene, viewport

    log(f"viewport SHADED clinical head {CLINICAL_SHAPE}: upsampling")
    try:
        grid, shape, index_to_world = clinical_head()
    except ct_head_data.Unavailable as e:
        return {"skipped": str(e)}
    voxel = float(np.linalg.norm(index_to_world[:3, :3], axis=0).min())
    views = orbit(index_to_world, shape, view_count)
    out = {"shape": shape, "spacing": np.linalg.norm(index_to_world[:3, :3], axis=0).tolist(),
           "active_voxels": grid.active_voxel_count, "threads": CLINICAL_THREADS, "load_before": os.getloadavg()[0],
           "transfer_functions": {}}
    for name, transfer_function in ct_head.TRANSFER_FUNCTIONS.items():
        log(f"viewport SHADED clinical head ({name}): full resolution")
        points, tf_range, opacity_scale = ramp_of(transfer_function, voxel)
        inputs, display = inputs_for('SHADED', grid, points, tf_range, opacity_scale, CLINICAL_THREADS, "CT head")
        start = time.perf_counter()
        prepared = prepared_scene.prepare(inputs)
        first = time_step(prepared, display, views[:1], viewport.STEPS[-1])[0]
        prepare_s = time.perf_counter() - start
        stats = []
        # The process's CPU seconds count only while its threads run: on a loaded machine, half of them per redraw
        # is what two idle cores would take at best, where the wall time counts the waits too.
        cpu_before = time.process_time()
        seconds = time_step(prepared, display, views, viewport.STEPS[-1], stats)
        cpu_per_redraw = (time.process_time() - cpu_before) / len(views)
        out["transfer_functions"][name] = {"median_s": statistics.median(seconds), "min_s": min(seconds),
                                           "cpu_s": cpu_per_redraw,
                                           "first_render_s": first, "prepare_and_first_s": prepare_s,
                                           "stages": stage_medians(stats)}
    out["load_after"] = os.getloadavg()[0]
    return out


MODES = ('XRAY', 'SHADED')


def run(quick=False, log=lambda message: None, modes=MODES, clinical_only=False):
    """Every measurement for `modes` (X-ray and shaded): a dict for results.json. `clinical_only`: the clinical
    head's alone (shaded)."""
    from pcvr_addon.render import prepared_scene

    if clinical_only:
        return {"clinical": clinical(QUICK_CLINICAL_VIEWS if quick else CLINICAL_VIEWS, log)}

    n = 64 if quick else 128
    grid, index_to_world = phantom_grid(n)
    views = orbit(index_to_world, (n, n, n), 4 if quick else ORBIT_VIEWS)
    results = {"n": n, "active_voxels": grid.active_voxel_count, "region": REGION, "modes": {},
               "date": datetime.datetime.now().astimezone().isoformat(timespec="minutes"),
               "load_before": os.getloadavg()[0]}
    for mode in modes:
        inputs, display = inputs_for(mode, grid)
        prepared = prepared_scene.prepare(inputs)
        log(f"viewport {mode}: steps")
        entry = {"steps": time_steps(prepared, display, views)}
        log(f"viewport {mode}: latency")
        entry["latency"] = latency(inputs, display, views)
        log(f"viewport {mode}: motion")
        entry["motion"] = motion(inputs, display, views, seconds=1.0 if quick else MOTION_SECONDS)
        results["modes"][mode] = entry
    if 'SHADED' in modes:
        results["full_resolution"] = full_resolution_at(64 if quick else AIM_N, 4 if quick else 6, log)
        results["clinical"] = clinical(QUICK_CLINICAL_VIEWS if quick else CLINICAL_VIEWS, log)
    results["load_after"] = os.getloadavg()[0]
    return results


def _ms(seconds):
    return f"{seconds * 1000:.0f}"


def clinical_section(clinical_results):
    """The clinical head's table (markdown lines)."""
    if not clinical_results:
        return []
    if "skipped" in clinical_results:
        return [f"The clinical-size CT head was skipped: {clinical_results['skipped']}", ""]
    c = clinical_results
    shape = " x ".join(map(str, c["shape"]))
    spacing = " x ".join(f"{s:.3f}" for s in c["spacing"])
    stage_names = ["native render" if key == "seconds" else key.removeprefix("seconds_").replace("_", " ")
                   for key in STAGE_SECONDS]
    lines = [f"Issue 36's aim: a clinical-size CT head ({shape} voxels of {spacing} mm, {c['active_voxels']:,} active: "
             "the InVesalius head of the shaded benchmark upsampled, as no public CT of that size could be fetched "
             f"here) shaded at full resolution ({REGION[0]} x {REGION[1]}) on {c['threads']} threads with ct_head.py's "
             f"transfer functions, once the scene is prepared and has rendered once; load average "
             f"{c['load_before']:.1f} before and {c['load_after']:.1f} after. *CPU ms / 2*: the process's CPU time per "
             "redraw over the two threads, what two idle cores would take at best. The native render's wall time and its "
             "stages are medians of its `stats` in ms (plan and shadows wall time, the other stages summed over the "
             "threads):", "",
             "| transfer function | median ms | least ms | CPU ms / 2 | first render ms | " + " | ".join(stage_names)
             + " | samples classified | aim |", "|---|---|---|---|---|" + "---|" * len(stage_names) + "---|---|"]
    for name, row in c["transfer_functions"].items():
        stages = " | ".join(_ms(row["stages"][key]) for key in STAGE_SECONDS)
        met = "met" if row["median_s"] * 1000 <= AIM_CLINICAL_MS else "missed"
        lines.append(f"| {name} | {_ms(row['median_s'])} | {_ms(row['min_s'])} | {_ms(row['cpu_s'] / 2)} | "
                     f"{_ms(row['first_render_s'])} | {stages} | "
                     f"{row['stages']['samples_classified'] / 1e6:.1f}M | {met} (<= {AIM_CLINICAL_MS:.0f}) |")
    return lines + [""]


def section(results):
    """The benchmark page's section (markdown lines)."""
    if not results:
        return []
    if "modes" not in results:  # the clinical head alone
        return ["## Rendered viewport", ""] + clinical_section(results.get("clinical"))
    names = {'XRAY': "X-ray", 'SHADED': "Shaded"}
    lines = ["## Rendered viewport", "",
             f"The CT phantom (`pcvr_native.phantoms.ct_phantom({results['n']})`, {results['active_voxels']:,} active "
             f"voxels) in a {results['region'][0]} x {results['region'][1]} viewport region, seen in perspective from "
             "views around it, through the add-on's viewport path (`tests/bench/viewport_bench.py`): the functions "
             "the viewport's worker thread runs (render a step, finish the image it draws), and its scheduler, "
             f"without Blender's window and the GPU upload. Medians; measured {results['date']} on all cores, load average {results['load_before']:.1f} "
             f"before and {results['load_after']:.1f} after (the machine is shared: on an idle one every time is "
             "smaller).", "",
             "| mode | step | image | sheet spacing | level of detail | ms | images/s |", "|---|---|---|---|---|---|---|"]
    for mode, entry in results["modes"].items():
        for row in entry["steps"]:
            spacing = f"{row['sheet_spacing']:g}x" if mode != 'XRAY' else "-"
            level = "as set" if row.get("level") is None else row["level"]
            lines.append(f"| {names[mode]} | 1/{row['scale']} | {row['width']} x {row['height']} | {spacing} | "
                         f"{level} | {_ms(row['median_s'])} | {1 / row['median_s']:.1f} |")
    lines += ["", "From a view change to the images it brings (the renderer chooses the first step from the "
              "timings it has measured; while the view moves 60 times a second, each first image finishes before "
              "the next change is taken up):", "",
              "| mode | first image | from step | full resolution | images/s while moving | aim |",
              "|---|---|---|---|---|---|"]
    for mode, entry in results["modes"].items():
        lat, mot = entry["latency"], entry["motion"]
        aim = f"first <= {AIM_FIRST_MS:.0f} ms" + (f", full <= {AIM_REFINED_XRAY_MS:.0f} ms" if mode == 'XRAY' else "")
        lines.append(f"| {names[mode]} | {_ms(lat['first_s'])} ms | 1/{lat['first_scale']} | {_ms(lat['full_s'])} ms "
                     f"| {mot['images_per_s']:.1f} | {aim} |")
    if "full_resolution" in results:
        full = results["full_resolution"]
        lines += ["", f"Shaded at full resolution ({results['region'][0]} x {results['region'][1]}) on the "
                  f"{full['n']}^3 phantom ({full['active_voxels']:,} active voxels), after a first render from each "
                  f"view; the aim is {AIM_FULL_SHADED_MS:.0f} ms:", "",
                  "| transfer function | median ms | least ms | aim |", "|---|---|---|---|"]
        labels = {"ramp": "the ramp above (soft tissue faint)", "skull": "the skull alone"}
        for name, row in full["ramps"].items():
            met = "met" if row["median_s"] * 1000 <= AIM_FULL_SHADED_MS else "missed"
            lines.append(f"| {labels[name]} | {_ms(row['median_s'])} | {_ms(row['min_s'])} | {met} |")
    return lines + [""] + clinical_section(results.get("clinical"))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="the 64^3 phantom, fewer views")
    parser.add_argument("--modes", nargs="+", choices=MODES, default=MODES, help="measure only these modes")
    parser.add_argument("--no-levels", action="store_true",
                        help="coarse steps at level 0 (as before they took coarser levels), to compare")
    parser.add_argument("--clinical-only", action="store_true", help="issue 36's clinical-size CT head alone")
    args = parser.parse_args(argv)
    if args.no_levels:
        from pcvr_addon.render import viewport
        viewport.LEVEL_PIXELS = 0.0
    results = run(args.quick, log=lambda message: print(message, file=sys.stderr), modes=tuple(args.modes),
                  clinical_only=args.clinical_only)
    print("\n".join(section(results)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
