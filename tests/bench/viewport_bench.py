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

    python tests/bench/viewport_bench.py [--quick] [--modes SHADED]     # prints the tables

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


def phantom_grid(n):
    from pcvr_native import phantoms
    phantom = phantoms.ct_phantom(n)
    return phantom.grid(), phantom.index_to_world


def inputs_for(mode, grid, points=RAMP):
    """RenderInputs and DisplayInputs of the phantom, as scene_inputs.read makes them from a Blender scene."""
    from pcvr_addon.scene import lighting, scene_inputs as si

    ramp = si.RampInputs(positions=tuple(p for p, _ in points), rgba=tuple(c for _, c in points), use_grid_range=False,
                         tf_min=0.0, tf_max=1.0, opacity_scale=1.0)
    volume = si.VolumeInputs(name="CT phantom", filepath="", grid_name=None,
                             object_to_world=tuple(map(tuple, np.eye(4))), density_scale=1.0,
                             ramp=ramp if mode == 'SHADED' else None,
                             # scene_inputs.material's tuple: shaded, Blinn-Phong 0.1 / 0.9 / 0.2 / 10, no ambient occlusion,
                             # (scattering octaves unused)
                             material=(True, 0.1, 0.9, 0.2, 10.0, None, False, 6) if mode == 'SHADED' else None, grid=grid)
    world = (0.05, 0.05, 0.05)
    sun = lighting.LightSpec("sun", SUN_DIRECTION, (1.0, 1.0, 1.0), 1.0)
    settings = dict(method="pcvr", splat_kernel="gauss1.4", stride=0)
    from pcvr_addon.scene import defaults
    inputs = si.RenderInputs(
        mode=mode, volumes=(volume,), threads=0,
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


def orbit(index_to_world, n, count):
    """`count` perspective views at 1280 x 720 around the phantom's centre, filling about 80% of the height."""
    from pcvr_addon.scene.camera import CameraView
    from pcvr_native.cameras import look_at, perspective

    centre = (np.asarray(index_to_world) @ np.array([(n - 1) / 2] * 3 + [1.0]))[:3]
    radius = np.linalg.norm(np.asarray(index_to_world)[:3, :3] @ np.full(3, n / 2))
    fov = math.radians(40.0)
    distance = radius / math.sin(fov / 2) / 0.8
    views = []
    for k in range(count):
        angle = 2 * math.pi * k / count
        eye = centre + distance * np.array([math.cos(angle) * 0.9, math.sin(angle) * 0.9, 0.44])
        views.append(CameraView(look_at(eye, centre), perspective(fov, REGION[0] / REGION[1], 0.1 * distance,
                                                                  10 * distance), *REGION))
    return views


def time_step(prepared, display, views, step):
    """Seconds of one viewport step (render and finish) from each of `views`."""
    from pcvr_addon.render import native_render, passes

    never = threading.Event()
    seconds = []
    for view in views:
        start = time.perf_counter()
        raw = native_render.render_viewport_step(prepared, view, step, never)
        passes.viewport_pixels(display, raw)
        seconds.append(time.perf_counter() - start)
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
    views = orbit(index_to_world, n, view_count)
    out = {"n": n, "active_voxels": grid.active_voxel_count, "ramps": {}}
    for name, points in (("ramp", RAMP), ("skull", SKULL_RAMP)):
        log(f"viewport SHADED {n}^3 ({name}): full resolution")
        inputs, display = inputs_for('SHADED', grid, points)
        prepared = prepared_scene.prepare(inputs)
        time_step(prepared, display, views, viewport.STEPS[-1])
        seconds = time_step(prepared, display, views, viewport.STEPS[-1])
        out["ramps"][name] = {"median_s": statistics.median(seconds), "min_s": min(seconds)}
    return out


MODES = ('XRAY', 'SHADED')


def run(quick=False, log=lambda message: None, modes=MODES):
    """Every measurement for `modes` (X-ray and shaded): a dict for results.json."""
    from pcvr_addon.render import prepared_scene

    n = 64 if quick else 128
    grid, index_to_world = phantom_grid(n)
    views = orbit(index_to_world, n, 4 if quick else ORBIT_VIEWS)
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
    results["load_after"] = os.getloadavg()[0]
    return results


def _ms(seconds):
    return f"{seconds * 1000:.0f}"


def section(results):
    """The benchmark page's section (markdown lines)."""
    if not results:
        return []
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
    return lines + [""]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="the 64^3 phantom, fewer views")
    parser.add_argument("--modes", nargs="+", choices=MODES, default=MODES, help="measure only these modes")
    parser.add_argument("--no-levels", action="store_true",
                        help="coarse steps at level 0 (as before they took coarser levels), to compare")
    args = parser.parse_args(argv)
    if args.no_levels:
        from pcvr_addon.render import viewport
        viewport.LEVEL_PIXELS = 0.0
    results = run(args.quick, log=lambda message: print(message, file=sys.stderr), modes=tuple(args.modes))
    print("\n".join(section(results)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
