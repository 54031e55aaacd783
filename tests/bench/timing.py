"""CPU time of a render, as the single-thread benchmarks take it (the machine is shared: CPU time
follows the work where wall time also follows the load)."""

from __future__ import annotations

import statistics
import time


def median_seconds(render, reps: int, clock=time.thread_time, pick=statistics.median) -> float:
    """Median (or `pick`) of `clock` seconds over `reps` calls of `render`, after one call that warms block
    caches and the first image's page faults."""
    render()
    times = []
    for _ in range(reps):
        t0 = clock()
        render()
        times.append(clock() - t0)
    return pick(times)


def least_cpu_seconds(render, reps: int) -> float:
    """The least CPU seconds of the calling thread over `reps` calls of `render`, after a warm-up call: on a
    shared machine other work only adds to a render's time (caches, memory bandwidth), so the least is the
    nearest to the render's own work; for curves whose every point should measure the same thing."""
    return median_seconds(render, reps, time.thread_time, pick=min)


def cpu_seconds(render, reps: int) -> float:
    """Median CPU seconds of the calling thread over `reps` calls of `render` (with threads=1 the
    render runs on it), after a warm-up call.

    The calling thread's time, not the process's: after oneTBB's workers have run (filling fresh
    zeroed pages for an image is parallel whatever the render's threads) they spin and yield for a
    while, and the process's CPU time counted that as the render's: measured on 128^3 blobs at
    magnification 8, 27-29 ms a render for the first eight or nine calls of a process, then 13 ms,
    with the same work."""
    return median_seconds(render, reps, time.thread_time)


def wall_seconds(render, reps: int) -> float:
    """Median wall seconds over `reps` calls of `render` (renders on all cores), after a warm-up call."""
    return median_seconds(render, reps, time.perf_counter)
