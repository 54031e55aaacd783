#!/usr/bin/env python3
"""Big volumes: the memory and time of an X-ray of a volume read whole against the same volume streamed from its
file (pcvr_native.stream_vdb) under memory limits, and of a zoomed-out view that renders a stream's kept level.

Each measurement runs in a fresh interpreter: open the file (read_vdb, or stream_vdb, which reads the topology
only), reset the peak resident memory (VmHWM, through /proc/self/clear_refs), render, and report the memory held
once the file is open, the render's peak above it, and the wall times.

| case        | what                                                                                        |
|-------------|---------------------------------------------------------------------------------------------|
| whole       | read_vdb, then render_xray                                                                   |
| streamed    | stream_vdb, then render_xray with memory_limit (half of it for a batch's voxels)            |
| zoomed out  | a stream at 1/128 pixel per voxel, twice: the first render makes the coarse level from every |
|             | batch, the second renders it from memory                                                    |

    python tests/bench/big_volume_bench.py [--quick]     # prints the table
"""

from __future__ import annotations

import datetime
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

MiB = 1 << 20

CHILD = r"""
import json, sys, time
import numpy as np
import pcvr_native as pn

path, opener, limit, magnification, renders = sys.argv[1], sys.argv[2], int(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5])

def resident():
    return int(open('/proc/self/statm').read().split()[1]) * 4096

def peak():
    return next(int(line.split()[1]) * 1024 for line in open('/proc/self/status') if line.startswith('VmHWM'))

before = resident()
start = time.perf_counter()
grid = getattr(pn, opener)(path)
opened_s = time.perf_counter() - start
opened = resident()
n = grid.index_bbox[1][0] + 1
# Orthographic, looking down the k axis of the box: `magnification` pixels per voxel.
side = max(8, round(n * magnification))
world_to_camera = np.eye(4)
world_to_camera[:3, 3] = (-(n - 1) / 2, -(n - 1) / 2, -4.0 * n)
projection = np.diag([2 * magnification / side, 2 * magnification / side, -1 / (4.0 * n), 1.0])
projection[2, 3] = -1.0
cam = pn.Camera(world_to_camera, projection, side, side)
with open('/proc/self/clear_refs', 'w') as f:
    f.write('5')
times, stats = [], {}
for _ in range(renders):
    start = time.perf_counter()
    pn.render_xray(grid, cam, memory_limit=limit or None, stats=stats)
    times.append(time.perf_counter() - start)
print(json.dumps({"open_bytes": opened - before, "open_s": opened_s, "render_peak_bytes": peak() - opened,
                  "render_s": times, "voxels": stats["voxels"], "batches": stats["batches"], "level": stats["level"],
                  "image": side}))
"""


def field(n):
    """An n^3 smooth field filling its box, with detail at a few voxels' scale, built a slab at a time."""
    x = np.linspace(-1.0, 1.0, n, dtype=np.float32)
    values = np.empty((n, n, n), dtype=np.float32)
    radial = x[:, None] ** 2 + x[None, :] ** 2
    ripple = np.sin(40 * x)[:, None] * np.cos(33 * x)[None, :]
    for k in range(n):
        values[:, :, k] = np.exp(-3 * (radial + x[k] ** 2)) * (1 + 0.3 * ripple * np.cos(21 * x[k]))
    return values


def measure(path, opener, limit, magnification, renders=1):
    proc = subprocess.run([sys.executable, "-c", CHILD, str(path), opener, str(limit), str(magnification), str(renders)],
                          capture_output=True, text=True, timeout=1800)
    if proc.returncode != 0:
        raise RuntimeError(f"{opener} child failed:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def run(quick, log):
    import pcvr_native as pn

    n = 192 if quick else 384
    limits = [32 * MiB] if quick else [32 * MiB, 128 * MiB]
    with tempfile.TemporaryDirectory(prefix="pcvr_big_") as work:
        path = Path(work) / f"field{n}.vdb"
        log(f"big volume: writing a {n}^3 field")
        pn.Grid.from_dense(field(n), np.eye(4)).write_vdb(str(path))
        file_bytes = path.stat().st_size
        stream = pn.stream_vdb(str(path))
        info = {"n": n, "active_voxels": stream.active_voxel_count, "value_bytes": stream.value_bytes,
                "file_bytes": file_bytes}
        del stream
        rows = []
        log("big volume: read whole")
        rows.append({"case": "whole", "limit": 0, **measure(path, "read_vdb", 0, 1.0)})
        for limit in limits:
            log(f"big volume: streamed, {limit // MiB} MiB")
            rows.append({"case": "streamed", "limit": limit, **measure(path, "stream_vdb", limit, 1.0)})
        log("big volume: zoomed out")
        rows.append({"case": "zoomed out", "limit": 0, **measure(path, "stream_vdb", 0, 1 / 128, renders=2)})
    return {"date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"), "load": os.getloadavg()[0],
            **info, "rows": rows}


def section(results) -> list[str]:
    """The benchmark page's section (markdown lines)."""
    if not results:
        return []
    lines = ["## Big volumes: bounded memory", "",
             f"A {results['n']}^3 smooth field ({results['active_voxels']:,} active voxels, "
             f"{results['value_bytes'] / MiB:.0f} MiB of values, a {results['file_bytes'] / MiB:.0f} MiB blosc file) "
             "in an orthographic X-ray at one pixel per voxel, read whole (`read_vdb`) or streamed from the file "
             "(`stream_vdb`: the topology in memory, the values a batch of 128^3 regions at a time, half the memory "
             "limit per batch), each in a fresh process (`tests/bench/big_volume_bench.py`). *Open* is the memory "
             "held once the file is open; *render peak* the render's peak resident memory above that (VmHWM). "
             "Zoomed out (1/128 pixel per voxel), a stream renders a coarse level, made from every batch on the "
             "first render and kept for the next. A streamed render's time includes reading and decompressing its "
             "values, which a whole read does while opening. "
             f"Wall times on all cores; measured {results['date']}, load "
             f"average {results['load']:.1f}.", "",
             "| case | memory limit | open | render peak | open s | render s | Mvoxels/s | batches | level |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in results["rows"]:
        limit = f"{r['limit'] // MiB} MiB" if r["limit"] else "-"
        renders = " then ".join(f"{t:.2f}" for t in r["render_s"])
        rate = results["active_voxels"] / r["render_s"][0] / 1e6
        lines.append(f"| {r['case']} | {limit} | {r['open_bytes'] / MiB:.0f} MiB | {r['render_peak_bytes'] / MiB:.0f} MiB | "
                     f"{r['open_s']:.2f} | {renders} | {rate:.0f} | {r['batches']} | {r['level']} |")
    return lines + [""]


if __name__ == "__main__":
    import standalone
    standalone.main(__doc__, run, section)
