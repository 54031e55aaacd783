#!/usr/bin/env python3
"""Batches: frames/s of a sequence and DRRs/s of a view sweep, in one process and on a local Dask cluster of 1
and 2 worker processes; the per-task and per-image overheads; a model of scaling to N machines from them.

| workload | what                                                                                         |
|----------|----------------------------------------------------------------------------------------------|
| sequence | F numbered .vdb files of an n^3 moving blob (`--frames 1-F`), X-ray at 2 pixels per voxel       |
| sweep    | the n^3 CT phantom from A angles about it (`--angles 0:360:360/A`): DRRs, X-ray at 2 px/voxel     |

Each configuration renders the whole batch after its workers have imported bpy and the add-on and rendered a
one-image batch of another volume, so the time is the batch's own: planning in Blender on the client, then reading
and rendering on the workers (each reads a volume once). Everything runs in a child process (Dask and bpy stay
out of the benchmark driver).

    python tests/bench/batch_bench.py [--quick]     # prints the section
"""

from __future__ import annotations

import dataclasses
import datetime
import json
import os
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

MACHINES = [1, 2, 4, 8, 16, 32, 64]
# Below this, the marginal planning time is lost in the timer's noise (a sequence's frames cost a path swap).
PLAN_RESOLUTION_S = 1e-4


def child(quick, work):
    """The measurements (run in a fresh interpreter): JSON on stdout's last line."""
    import numpy as np

    sys.path[:0] = [str(REPO), str(REPO / "tests" / "batch")]
    import batch_helpers as bh
    import batch_scenes
    import pcvr_native as pn
    from pcvr_native import phantoms
    from pcvr_addon.batch import dask_runner, jobs, plan, run

    n = 64 if quick else 128
    frames = 8 if quick else 24
    angles = 24 if quick else 72
    work = Path(work)
    batch_scenes.write_sequence(work / "seq", range(1, frames + 1), size=n)
    ct = phantoms.ct_phantom(n)
    pn.Grid.from_dense(ct.values, ct.index_to_world).write_vdb(str(work / "ct.vdb"))
    batch_scenes.write_sequence(work / "warm", [1], size=16)
    def sweep(count):
        return jobs.expand(str(work / "ct.vdb"), "OUT/v_####.exr", angles=jobs.parse_angles(f"0:360:{360 / count}"),
                           options={"magnification": 2.0})

    sequence = jobs.expand(str(work / "seq" / "smoke_####.vdb"), "OUT/f_####.exr", range(1, frames + 1),
                           options={"magnification": 2.0})
    workloads = {"sequence": sequence, "sweep": sweep(angles)}
    # Twice as many images to plan: the sequence's frames twice over (a frame costs a path swap), twice the angles
    # (each angle a camera turn and a read of the scene).
    doubled = {"sequence": sequence + sequence, "sweep": sweep(2 * angles)}
    defaults = bh.defaults()
    warm = jobs.expand(str(work / "warm" / "smoke_0001.vdb"), "OUT/warm.exr")
    results = {"n": n, "frames": frames, "angles": angles, "cpus": os.cpu_count(), "configurations": [],
               "planning": {}}

    def batch(job_list, directory, client):
        placed = [dataclasses.replace(j, output=j.output.replace("OUT", str(directory))) for j in job_list]
        start = time.perf_counter()
        status = run.render_batch(placed, str(directory / "m.manifest.json"), defaults, client, stream=open(os.devnull, "w"))
        seconds = time.perf_counter() - start
        assert status == 0
        with open(directory / "m.manifest.json") as file:
            entries = json.load(file)["jobs"]
        return seconds, entries

    def plan_seconds(job_list):
        """The least of 3 (other work on the machine only adds)."""
        times = []
        for _ in range(3):
            start = time.perf_counter()
            plan.plan(job_list, defaults, 0)
            times.append(time.perf_counter() - start)
        return min(times)

    # Planning runs on the client, wherever the images render: measured once. What one more image costs to
    # plan: twice the images, less once.
    for name, job_list in workloads.items():
        once = plan_seconds(job_list)
        results["planning"][name] = {"plan_s": once, "plan_marginal_s": max(
            0.0, plan_seconds(doubled[name]) - once) / len(job_list)}

    for workers in (None, 1, 2):
        client = dask_runner.connect(workers=workers) if workers else None
        try:
            if client is not None:
                start = time.perf_counter()
                count = 200
                client.gather(client.map(lambda x: x, range(count), pure=False))
                task_overhead = (time.perf_counter() - start) / count
            else:
                task_overhead = 0.0
            if client is not None:
                client.run(_import_renderer)  # on every worker: the warm-up batch reaches only one
            batch(warm, work / f"warm_{workers}", client)
            row = {"workers": workers or 0, "task_overhead_s": task_overhead}
            for name, job_list in workloads.items():
                seconds, entries = batch(job_list, work / f"{name}_{workers}", client)
                job_s = [entry["seconds"] for entry in entries]
                native_s = [entry["stats"]["seconds"] for entry in entries]
                row[name] = {"images": len(entries), "seconds": seconds,
                             "job_s": float(np.mean(job_s)), "native_s": float(np.mean(native_s))}
            results["configurations"].append(row)
        finally:
            if client is not None:
                dask_runner.close(client)
    print(json.dumps(results))


def _import_renderer():
    from pcvr_addon.io import image_io
    from pcvr_addon.batch import render_task  # noqa: F401  (bpy, the add-on, pcvr_native)
    image_io.openimageio()


def run(quick, log):
    import tempfile

    log("batch: sequence and sweep in one process and on 1 and 2 Dask workers")
    with tempfile.TemporaryDirectory(prefix="pcvr_batch_") as work:
        started = time.time()
        load = os.getloadavg()[0]
        proc = subprocess.run([sys.executable, __file__, "--child", work] + (["--quick"] if quick else []),
                              capture_output=True, text=True, timeout=1800, cwd=REPO)
        if proc.returncode != 0:
            raise RuntimeError(f"batch bench child failed:\n{proc.stderr[-3000:]}")
        results = json.loads(proc.stdout.strip().splitlines()[-1])
    return {"date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"), "load": load,
            "load_after": os.getloadavg()[0], "wall_s": time.time() - started, **results}


def model(results, workload):
    """Images/s of a long batch (fixed costs spread thin) on N machines like this one, each running one worker:
    the client plans every image in Blender, serially (the marginal planning time per image), while the workers
    render in parallel at the 1-worker rate (its batch time less its planning, per image: reading, rendering,
    writing and the task round trips). Returns ({N: images/s}, the planning limit in images/s)."""
    one = next(row for row in results["configurations"] if row["workers"] == 1)[workload]
    planning = results["planning"][workload]
    per_image = max(0.0, one["seconds"] - planning["plan_s"]) / one["images"]
    plan_s = max(planning["plan_marginal_s"], PLAN_RESOLUTION_S)
    return {machines: 1.0 / (plan_s + per_image / machines) for machines in MACHINES}, 1.0 / plan_s


def section(results) -> list[str]:
    """The benchmark page's section (markdown lines)."""
    if not results:
        return []
    name = {0: "one process", 1: "Dask, 1 worker", 2: "Dask, 2 workers"}
    lines = ["## Batches: sequences and view sweeps over Dask", "",
             f"A sequence of {results['frames']} frames of a {results['n']}^3 moving blob and a sweep of "
             f"{results['angles']} DRRs of the {results['n']}^3 CT phantom, X-ray at 2 pixels per voxel "
             "(`tests/bench/batch_bench.py`, [rendering at scale](rendering-at-scale.md)). Each batch runs after "
             "its workers imported bpy and the add-on and rendered a one-image batch; its time includes planning (Blender on the client) and "
             "reading each volume once per worker. *Image* is the mean time a worker spends on one image (read, "
             "render, write), *native* the render call alone. "
             f"{results['cpus']} CPUs; measured {results['date']}, load average {results['load']:.1f} before and "
             f"{results['load_after']:.1f} after.", "",
             "| where | frames/s | DRRs/s | image ms | native ms | task round trip ms |",
             "|---|---|---|---|---|---|"]
    for row in results["configurations"]:
        seq, sweep = row["sequence"], row["sweep"]
        trip = f"{1e3 * row['task_overhead_s']:.1f}" if row["workers"] else "-"
        lines.append(f"| {name[row['workers']]} | {seq['images'] / seq['seconds']:.1f} | "
                     f"{sweep['images'] / sweep['seconds']:.1f} | "
                     f"{1e3 * (seq['job_s'] + sweep['job_s']) / 2:.0f} | {1e3 * (seq['native_s'] + sweep['native_s']) / 2:.0f} | "
                     f"{trip} |")
    planning = results["planning"]
    lines += ["", "Planning on the client (Blender, the least of 3): "
              + "; ".join(f"{label} {1e3 * planning[w]['plan_s']:.0f} ms for the batch, "
                          f"{1e3 * planning[w]['plan_marginal_s']:.2f} ms for each image more"
                          for w, label in (("sequence", "the sequence"), ("sweep", "the sweep"))) + "."]
    lines += ["", "Modelled images/s of a long batch on N machines like this one, one worker each: the client plans "
              "each image (serial, at the marginal planning time: planning twice the images, less once), the "
              "workers render at the 1-worker row's time per image (reading, rendering, writing, task round trips), "
              "divided by N:", "",
              "| workload | " + " | ".join(f"N={m}" for m in MACHINES) + " | planning limit |",
              "|---|" + "---|" * (len(MACHINES) + 1)]
    for workload, label in (("sequence", "frames/s"), ("sweep", "DRRs/s")):
        rates, limit = model(results, workload)
        shown = f"> {limit:,.0f}" if limit >= 1 / PLAN_RESOLUTION_S else f"{limit:,.0f}"
        lines.append(f"| {label} | " + " | ".join(f"{rates[m]:,.0f}" for m in MACHINES) + f" | {shown} |")
    return lines + [""]


if __name__ == "__main__":
    if "--child" in sys.argv:
        child("--quick" in sys.argv, sys.argv[sys.argv.index("--child") + 1])
    else:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        import standalone
        standalone.main(__doc__, run, section)
