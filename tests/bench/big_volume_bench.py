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
| shaded, MIP | a CT-like 512 x 512 x 361 volume read whole against streamed in bricks under 32 MiB, each    |
|             | twice, alternated, with the two images' difference (`--shaded-only`: just these)            |

    python tests/bench/big_volume_bench.py [--quick]     # prints the table
    python tests/bench/big_volume_bench.py --shaded-only  # only the shaded and MIP rows, printed
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

# Both children: open argv[1] with pcvr_native.<argv[2]> (read_vdb, stream_vdb), measuring memory and time.
OPEN_IN_CHILD = r"""
import json, sys, time
import numpy as np
import pcvr_native as pn

def resident():
    return int(open('/proc/self/statm').read().split()[1]) * 4096

def peak():
    return next(int(line.split()[1]) * 1024 for line in open('/proc/self/status') if line.startswith('VmHWM'))

before = resident()
start = time.perf_counter()
grid = getattr(pn, sys.argv[2])(sys.argv[1])
opened_s = time.perf_counter() - start
opened = resident()
"""

CHILD = OPEN_IN_CHILD + r"""
limit, magnification, renders = int(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5])
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


# Shaded and MIP of a CT-like volume, read whole or streamed in bricks: argv path, opener, limit, mode, output .npy.
SHADED_CHILD = OPEN_IN_CHILD + r"""
from pcvr_native import cameras

limit, mode, out = int(sys.argv[3]), sys.argv[4], sys.argv[5]
(i0, j0, k0), (i1, j1, k1) = grid.index_bbox
centre = np.array([(i0 + i1) / 2, (j0 + j1) / 2, (k0 + k1) / 2])
radius = 0.5 * float(np.linalg.norm([i1 - i0, j1 - j0, k1 - k0])) + 4
# Orthographic, tilted so that bricks occlude one another, about one pixel per voxel.
direction = np.array([0.3, -0.5, -0.8]) / np.linalg.norm([0.3, -0.5, -0.8])
cam = pn.Camera(cameras.look_at(centre - direction * 3 * radius, centre),
                cameras.ortho(-radius, radius, -radius, radius, radius, 5 * radius), int(2 * radius), int(2 * radius))
tf = pn.TransferFunction(density=[-1000, -200, 0, 100, 300, 1000, 3000],
                         rgba=[[0, 0, 0, 0], [0, 0, 0, 0], [0.8, 0.4, 0.3, 0.05], [0.8, 0.4, 0.3, 0.1], [1, 1, 0.9, 0.2],
                               [1, 1, 1, 0.9], [1, 1, 1, 0.95]])
kwargs = {"memory_limit": limit} if limit else {}
stats = {}
with open('/proc/self/clear_refs', 'w') as f:
    f.write('5')
start = time.perf_counter()
if mode == "shaded":
    # Splatted: "auto" samples the sheets where the volume's lattice fits in a quarter of the memory available at
    # the time, which on a shared machine changes from one process to the next.
    image = pn.render_shaded(grid, cam, tf, lights=[pn.Light.sun(direction=(-0.5, -0.2, -0.8))], stats=stats,
                             sheet_fill="splat", **kwargs)
else:
    image = pn.render_mip(grid, cam, stats=stats, **kwargs)
render_s = time.perf_counter() - start
np.save(out, image)
print(json.dumps({"open_bytes": opened - before, "open_s": opened_s, "render_peak_bytes": peak() - opened,
                  "process_peak_bytes": peak(), "render_s": [render_s], "batches": stats["batches"],
                  "brick_bytes": stats["memory_bytes"], "image": cam.width}))
"""


def ct_like_slabs(shape, planes=16):
    """A CT-like volume in Hounsfield units, every voxel active as in a scan (air -1000, soft tissue near 40,
    skull 1000, ventricles 0, lesions), made a slab of i-planes at a time from the ellipsoids of the 3-D
    Shepp-Logan head (pcvr_native.phantoms.ct_phantom) stretched over the box, with a little noise."""
    ellipsoids = [(1.0, (0.69, 0.92, 0.81), (0.0, 0.0, 0.0)), (-0.8, (0.6624, 0.874, 0.78), (0.0, -0.0184, 0.0)),
                  (-0.2, (0.11, 0.31, 0.22), (0.22, 0.0, 0.0)), (-0.2, (0.16, 0.41, 0.28), (-0.22, 0.0, 0.0)),
                  (0.1, (0.21, 0.25, 0.41), (0.0, 0.35, -0.15)), (0.1, (0.046, 0.046, 0.05), (0.0, 0.1, 0.25))]
    # (the phantom's first six ellipsoids, axis-aligned)
    rng = np.random.default_rng(0)
    axes = [np.linspace(-1.0, 1.0, n, dtype=np.float32) for n in shape]
    for i in range(0, shape[0], planes):
        x, y, z = np.meshgrid(axes[0][i:i + planes], axes[1], axes[2], indexing="ij", sparse=True)
        value = np.zeros((len(axes[0][i:i + planes]), shape[1], shape[2]), dtype=np.float32)
        for amplitude, (a, b, c), (cx, cy, cz) in ellipsoids:
            q = np.sqrt(((x - cx) / a) ** 2 + ((y - cy) / b) ** 2 + ((z - cz) / c) ** 2)
            value += np.float32(amplitude) * np.clip((1.0 - q) * 100.0 + 0.5, 0.0, 1.0)  # ramps of a voxel or so
        hounsfield = np.interp(value, [0.0, 0.2, 1.0], [-1000.0, 40.0, 1000.0]) + rng.normal(0.0, 5.0, value.shape)
        yield np.where(hounsfield == -1000.0, -1000.5, hounsfield).astype(np.float32)


def measure_shaded(path, opener, limit, mode, out):
    proc = subprocess.run([sys.executable, "-c", SHADED_CHILD, str(path), opener, str(limit), mode, str(out)],
                          capture_output=True, text=True, timeout=3600)
    if proc.returncode != 0:
        raise RuntimeError(f"{opener} {mode} child failed:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def run_shaded(quick, log, rounds=2):
    """Whole against streamed in bricks, shaded and MIP, alternated `rounds` times (the machine is shared)."""
    import pcvr_native as pn

    shape = (256, 256, 181) if quick else (512, 512, 361)
    limit = 32 * MiB
    with tempfile.TemporaryDirectory(prefix="pcvr_bricks_") as work:
        path = Path(work) / "ct_like.vdb"
        log(f"big volume: writing a CT-like {shape} volume")
        xf = np.diag([0.5, 0.5, 0.7, 1.0])
        pn.Grid.from_slabs(ct_like_slabs(shape), shape, xf, background=-1000.0).write_vdb(str(path))
        stream = pn.stream_vdb(str(path))
        info = {"shape": list(shape), "active_voxels": stream.active_voxel_count, "value_bytes": stream.value_bytes,
                "file_bytes": path.stat().st_size, "limit": limit, "load_before": os.getloadavg()[0]}
        del stream
        rows = []
        for mode in ("shaded", "mip"):
            for round_index in range(rounds):
                pair = {}
                for case, opener, case_limit in (("whole", "read_vdb", 0), ("bricks", "stream_vdb", limit)):
                    log(f"big volume: {mode} {case}, round {round_index + 1}")
                    out = Path(work) / f"{mode}_{case}.npy"
                    pair[case] = measure_shaded(path, opener, case_limit, mode, out)
                    pair[case]["image_array"] = np.load(out)
                difference = float(np.abs(pair["bricks"]["image_array"] - pair["whole"]["image_array"]).max())
                rms = float(np.sqrt(np.mean((pair["bricks"]["image_array"] - pair["whole"]["image_array"]) ** 2)))
                for case in ("whole", "bricks"):
                    del pair[case]["image_array"]
                    rows.append({"mode": mode, "case": case, "round": round_index + 1, **pair[case],
                                 "max_difference": difference, "rms_difference": rms})
        info["load_after"] = os.getloadavg()[0]
    return {"date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"), **info, "rows": rows}


def shaded_section(results) -> list[str]:
    if not results:
        return []
    shape = " x ".join(str(n) for n in results["shape"])
    lines = ["### Shaded and MIP in bricks", "",
             f"A CT-like {shape} volume (every voxel active, as in a scan: {results['value_bytes'] / MiB:.0f} MiB of "
             f"values, a {results['file_bytes'] / MiB:.0f} MiB file) rendered shaded and as a MIP, orthographic and tilted, "
             "at about a pixel per voxel (shaded sheets splatted), read whole (`read_vdb`), or streamed in bricks under a "
             f"{results['limit'] // MiB} MiB memory limit (`stream_vdb`, then `render_shaded(stream, ..., memory_limit=...)`: "
             "bricks as large as the limit lets the render's working set be, each read with its margin and rendered front "
             "to back; *counted*: that working set as the render counts it against the limit, stats `memory_bytes`). "
             "Each in a fresh process, whole and bricks alternated; *process peak* is the process's peak resident "
             "memory (VmHWM), *render peak* that above the memory held once the file was open. *Difference*: the "
             "largest and RMS difference between the two images. "
             f"Measured {results['date']}, load average {results['load_before']:.1f} before and "
             f"{results['load_after']:.1f} after (2 cores shared with other sessions).", "",
             "| mode | case | round | process peak | render peak | open s | render s | bricks | counted | difference (max, RMS) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in results["rows"]:
        bricks = str(r["batches"]) if r["batches"] else "-"
        brick = f"{r['brick_bytes'] / MiB:.1f} MiB" if r["brick_bytes"] else "-"
        lines.append(f"| {r['mode']} | {r['case']} | {r['round']} | {r['process_peak_bytes'] / MiB:.0f} MiB | "
                     f"{r['render_peak_bytes'] / MiB:.0f} MiB | {r['open_s']:.2f} | {r['render_s'][0]:.2f} | {bricks} | {brick} | "
                     f"{r['max_difference']:.2g}, {r['rms_difference']:.2g} |")
    return lines + [""]


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
            **info, "rows": rows, "shaded": run_shaded(quick, log)}


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
    return lines + [""] + shaded_section(results.get("shaded"))


if __name__ == "__main__":
    if "--shaded-only" in sys.argv:
        print("\n".join(shaded_section(run_shaded("--quick" in sys.argv, lambda m: print(m, file=sys.stderr, flush=True)))))
        sys.exit(0)
    import standalone
    standalone.main(__doc__, run, section)
