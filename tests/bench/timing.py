"""CPU time of a render, as the single-thread benchmarks take it (the machine is shared: CPU time
follows the work where wall time also follows the load)."""

from __future__ import annotations

import statistics
import time


def cpu_seconds(render, reps: int) -> float:
    """Median CPU seconds of `reps` calls of `render`, after one call that warms block caches and
    the first image's page faults."""
    render()
    times = []
    for _ in range(reps):
        t0 = time.process_time()
        render()
        times.append(time.process_time() - t0)
    return statistics.median(times)
