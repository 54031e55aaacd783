# SPDX-License-Identifier: GPL-3.0-or-later

"""Running a batch's tasks on Dask distributed: a LocalCluster of worker processes started here (`--workers N`),
or a running scheduler joined (`--scheduler ADDRESS`, with `dask scheduler` and `dask worker` started on the
machines; every worker needs this add-on, bpy and pcvr_native importable, and the volumes and outputs at the
same paths: shared storage).

Each worker runs one task at a time (one thread: the native renderers use every core themselves), so a
worker's memory holds one render and its cached grids. A worker lost mid-run costs only its unfinished tasks:
the scheduler gives them to another worker, whose render_task leaves alone the images already written in this
run (render_task.py). Only this module imports `distributed`; the add-on in Blender never does.
"""

import logging
import math
import os
import sys


class DaskUnavailable(ImportError):
    pass


def _distributed():
    try:
        import distributed
    except ImportError:
        raise DaskUnavailable("--workers and --scheduler need Dask distributed: pip install distributed") from None
    return distributed


def connect(workers=None, scheduler=None, memory_limit="auto"):
    """A distributed.Client of a new LocalCluster of `workers` processes (each `memory_limit`, Dask's 'auto'
    shares the machine's memory out), or of the scheduler at `scheduler`. Close it with close()."""
    distributed = _distributed()
    if scheduler is not None:
        return distributed.Client(scheduler)
    _put_blender_script_paths_last()
    cluster = distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                       memory_limit=memory_limit, dashboard_address=None,
                                       silence_logs=logging.ERROR)
    return distributed.Client(cluster)


def close(client):
    cluster = client.cluster
    client.close()
    if cluster is not None:
        cluster.close()


def _put_blender_script_paths_last():
    """Move the script folders that importing bpy puts at the front of sys.path to its end. Worker processes
    start with this process's sys.path (also when the nanny restarts one whose process died), and there
    Blender's `scripts/modules/bpy` package would hide the bpy module itself ("No module named '_bpy'").
    This process's bpy is imported already, and nothing else has those folders' names."""
    bpy = sys.modules.get("bpy")
    if bpy is None:
        return
    scripts = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(bpy.__file__)))) + os.sep
    blender = [path for path in sys.path if os.path.abspath(path).startswith(scripts)]
    sys.path[:] = [path for path in sys.path if path not in blender] + blender


def worker_count(client, wait_seconds=30):
    """The workers the scheduler has (waiting up to `wait_seconds` for one). OSError when none comes."""
    try:
        client.wait_for_workers(1, timeout=wait_seconds)
    except TimeoutError:
        raise OSError(f"no Dask worker joined the scheduler at {client.scheduler.address} within "
                      f"{wait_seconds} s: start some with `dask worker {client.scheduler.address} --nthreads 1`")
    return len(client.scheduler_info()["workers"])


def smallest_memory_limit(client):
    """The least memory a worker may use (bytes), or None when none is limited."""
    limits = [info.get("memory_limit") or 0 for info in client.scheduler_info()["workers"].values()]
    limits = [limit for limit in limits if limit > 0]
    return min(limits) if limits else None


def task_size(jobs, workers, tasks_per_worker=4):
    """Jobs per task: a few tasks per worker, so that a lost worker costs little and the last tasks balance,
    and at most 16 (a task's results come back at once)."""
    return max(1, min(16, math.ceil(jobs / (tasks_per_worker * max(workers, 1)))))


def run_tasks(client, tasks, run_id, done):
    """Render `tasks` (lists of PlannedJob) on the cluster; `done(results)` is called with each task's
    JobResults as it finishes. Tasks are named by the run and their place, so that a task resubmitted by this
    run is the same task."""
    from . import render_task

    distributed = _distributed()
    futures = [client.submit(render_task.render_task, task, run_id, key=f"pcvr-render-{run_id}-{number}",
                             pure=False, retries=1)
               for number, task in enumerate(tasks)]
    try:
        for future in distributed.as_completed(futures):
            done(future.result())
    finally:
        client.cancel(futures)
