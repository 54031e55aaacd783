# SPDX-License-Identifier: GPL-3.0-or-later

"""A batch's unit of work: render a task's PlannedJobs and write their images. The one function that renders in
a batch, in this process or on a Dask worker, so that both give the same bits.

It runs the render engine's own stages after reading the scene (render.prepared_scene.prepare,
render.native_render.render_raw, render.passes.finish: F12's code), which touch no Blender data, and writes the
passes as `python -m pcvr_addon render` does (io.image_io.write_passes). Grids come through the engine's cache
(render.cache.grids), which lives as long as the process: a worker reads a volume once for all the views of it
it renders, in this task and the next.

Each image is written to a temporary file and renamed into place, and carries the batch's run id in its
ImageDescription: a task run again (Dask retries the tasks of a worker lost mid-run) leaves alone the images
this run already wrote, so none is written twice, and none is ever seen half-written.
"""

import os
import socket
import time
from dataclasses import dataclass, field

from ..io import image_io
from ..render import native_render, passes, prepared_scene


@dataclass
class JobResult:
    index: int                 # PlannedJob.index
    output: str
    status: str                # "rendered", "kept" (written earlier in this run), "failed"
    seconds: float = 0.0       # reading, rendering and writing
    stats: dict = field(default_factory=dict)
    errors: list = field(default_factory=list)
    worker: str = ""           # host:pid that rendered it


def run_description(run_id, index):
    return f"PCVR batch {run_id} job {index}"


def render_task(planned_jobs, run_id, progress=None, prepare=None):
    """Render and write each PlannedJob; JobResult of each. `progress(result)` is told of each as it is done.
    `prepare`: a render.prepared_scene.Preparer to share with the batch's other tasks in this process (None: the
    task's own)."""
    results = []
    # Jobs with the same inputs (a sweep of views of one volume) share one prepared scene: the grid placed, and mapped
    # to attenuation where it holds Hounsfield units, once. A Dask worker's is never kept past the task, whose files
    # may change before the next run's.
    prepare = prepare or prepared_scene.Preparer()
    for planned in planned_jobs:
        result = render_job(planned, run_id, prepare)
        results.append(result)
        if progress is not None:
            progress(result)
    return results


def render_job(planned, run_id, prepare=prepared_scene.prepare, rendered=None):
    """Render and write one PlannedJob, its scene made by `prepare` (a Preparer shares one between jobs).
    `rendered` (raw, stats): native results rendered elsewhere (the shares of a split frame, composited:
    split_frame.py), which this finishes and writes."""
    import pcvr_native

    description = run_description(run_id, planned.index)
    worker = f"{socket.gethostname()}:{os.getpid()}"
    output = planned.job.output
    if os.path.exists(output) and image_io.description_of(output) == description:
        return JobResult(planned.index, output, "kept", worker=worker)
    start = time.perf_counter()
    try:
        if rendered is None:
            prepared = prepare(planned.inputs)
            if prepared.errors:
                # Unlike F12, which shows the volumes it could read, a batch writes no image without them:
                # --skip-existing then renders it again once its files are there.
                return JobResult(planned.index, output, "failed", time.perf_counter() - start,
                                 errors=list(prepared.errors), worker=worker)
            stats = {}
            raw = native_render.render_raw(prepared, planned.view, stats=stats)
        else:
            raw, stats = rendered
        pixels = passes.finish(planned.display, raw)
        directory = os.path.dirname(os.path.abspath(output))
        os.makedirs(directory, exist_ok=True)
        if planned.job.options.get("cone_beam") is not None:
            image_io.write_drr(output, pixels["XRay"][:, :, 0], planned.job.options.get("intensity"), description=description)
        else:
            image_io.write_passes(output, pixels, description=description)
    except (OSError, ValueError, RuntimeError, MemoryError, pcvr_native.RenderCancelled) as ex:
        return JobResult(planned.index, output, "failed", time.perf_counter() - start, errors=[str(ex)],
                         worker=worker)
    return JobResult(planned.index, output, "rendered", time.perf_counter() - start, _plain(stats), worker=worker)


def _plain(stats):
    """The native statistics as JSON takes them."""
    return {key: (list(value) if isinstance(value, (list, tuple)) else value) for key, value in stats.items()}
