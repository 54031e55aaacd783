#!/usr/bin/env python3
"""Speed of light of the X-ray splat on this machine: measured primitives and the bounds they set.

Compiles ``sol_kernels.c`` (beside this file) with ``cc -O3 -march=native -fopenmp`` and runs it; see
the table at the top of that file for what each test does. :func:`bounds` turns the measurements into
upper limits on active voxels per second for a splat with a given number of taps per voxel:

| bound   | model                                                                                  |
|---------|----------------------------------------------------------------------------------------|
| memory  | every active voxel is read once: 4 bytes of value + 1 bit of mask + the block header     |
|         | (about 4.3 bytes), at the measured DRAM read bandwidth                                   |
| store   | accumulators are doubles, so one 256-bit store carries 4 taps: taps / 4 stores per voxel,|
|         | at the measured 256-bit store rate (L1-resident target, all cores)                       |
| compute | the least arithmetic a tap needs: per 8 taps 2 FMAs for rho^2 (a quadratic in the       |
|         | offsets), 1 multiply by the voxel's value and 2 four-wide double adds into the           |
|         | accumulator: 5 vector ops per 8 taps at the measured FMA rate (lookup and conversions    |
|         | not counted, so this is a bound, not an estimate)                                        |
| gather  | one table lookup per tap, at the measured 8-lane gather rate (lanes per second)          |

The speed of light is the smallest of the first three (what any implementation must pay); the
gather bound belongs to the table-lookup formulation the renderer uses today, which is why it is
listed on its own. Run directly (``python tests/bench/speed_of_light.py``) to print the numbers.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
SOURCE = HERE / "sol_kernels.c"

BYTES_PER_VOXEL = 4.0 + 1.0 / 8.0 + 88.0 / 512.0  # value + mask bit + VoxelBlock header per 512 voxels
OPS_PER_8_TAPS = 5.0


def pcvr_taps() -> float:
    """PCVR's footprint: at most 4 x 4 subgrid nodes (radius 2 voxels, one node per voxel)."""
    return 16.0


def regular_taps(magnification: float, radius: float = 2.0) -> float:
    """Classic splatting: the footprint disc of radius `radius` voxels at `magnification` pixels each."""
    return math.pi * (radius * magnification) ** 2


def compile_kernels(build_dir: Path) -> Path:
    build_dir.mkdir(parents=True, exist_ok=True)
    exe = build_dir / "sol_kernels"
    cc = os.environ.get("CC", "cc")
    if shutil.which(cc) is None:
        raise RuntimeError(f"no C compiler ({cc}) on PATH")
    cmd = [cc, "-O3", "-march=native", "-fopenmp", str(SOURCE), "-o", str(exe), "-lm"]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    return exe


def measure(build_dir: Path, n: int = 256, gx=(0.8660, 0.0, -0.5), gy=(-0.1710, 0.9397, -0.2962),
            log=lambda s: None) -> dict:
    """Run every micro-benchmark. Returns {"tests": {(test, threads): record}, "threads": [...]}.

    `gx`, `gy`: subgrid node coordinates per index step (the projection the splat tests use).
    """
    exe = compile_kernels(build_dir)
    args = [str(exe), str(n)] + [f"{v:.6f}" for v in (*gx, *gy)]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, text=True)
    tests = {}
    for line in proc.stdout:
        rec = json.loads(line)
        tests[(rec["test"], rec["threads"])] = rec
        log(f"  sol {rec['test']:16s} threads={rec['threads']}: "
            + ", ".join(f"{k}={v:.4g}" for k, v in rec.items() if k not in ("test", "threads") and isinstance(v, float)))
    if proc.wait() != 0:
        raise RuntimeError(f"{exe} failed with exit status {proc.returncode}")
    threads = sorted({t for (_, t) in tests})
    return {"tests": tests, "threads": threads, "n": n}


def get(measured: dict, test: str, key: str, threads: int | None = None) -> float:
    """One measured number; `threads` None means all cores (the largest count measured)."""
    t = max(measured["threads"]) if threads is None else threads
    rec = measured["tests"].get((test, t))
    return float(rec[key]) if rec and key in rec else float("nan")


def machine_rate(measured: dict, test: str, key: str, per_core: bool = True) -> float:
    """What all cores can do. Per-core resources (FMA pipes, store ports, gather units) scale with the
    cores, so this is cores x the single-thread rate unless the all-core run measured more: on a shared
    machine the all-core runs are the ones other work disturbs most. DRAM bandwidth is shared: the
    best of the single-thread and all-core runs."""
    cores = max(measured["threads"])
    one, all_ = get(measured, test, key, 1), get(measured, test, key, cores)
    if per_core:
        return max(all_, one * cores) if not math.isnan(all_) else one * cores
    return max(one, all_) if not math.isnan(all_) else one


def bounds(measured: dict, taps: float) -> dict:
    """Upper limits on voxels per second, all cores, for a splat of `taps` taps per voxel (see the
    module docstring)."""
    bw = machine_rate(measured, "bw_read", "gbps", per_core=False) * 1e9
    stores = machine_rate(measured, "store_ymm", "stores_per_s")
    fma = machine_rate(measured, "fma_ymm", "fma_per_s")
    gathers = machine_rate(measured, "gather_ymm", "gathers_per_s") * 8.0
    out = {
        "memory": bw / BYTES_PER_VOXEL,
        "store": stores / (taps / 4.0),
        "compute": fma / (taps / 8.0 * OPS_PER_8_TAPS),
        "gather": gathers / taps,
    }
    out["sol"] = min(out["memory"], out["store"], out["compute"])
    out["sol_limiter"] = min(("memory", "store", "compute"), key=lambda k: out[k])
    return out


def main() -> int:
    build = Path(os.environ.get("PCVR_BENCH_BUILD", HERE.parents[1] / "out" / "bench"))
    m = measure(build, log=lambda s: print(s, file=sys.stderr))
    for name, taps in (("pcvr 4x4", pcvr_taps()), ("regular m=4", regular_taps(4)), ("regular m=8", regular_taps(8))):
        b = bounds(m, taps)
        print(f"{name:12s} taps={taps:6.1f}  " + "  ".join(
            f"{k}={v / 1e6:8.1f}M/s" for k, v in b.items() if isinstance(v, float)) + f"  (limited by {b['sol_limiter']})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
