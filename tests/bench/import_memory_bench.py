#!/usr/bin/env python3
"""Scan conversion's memory and time: a CT-like DICOM series and the same volume as .nii.gz, converted to
.vdb a slab at a time (pcvr_addon.volume_import: Grid.from_slabs), against reading the whole array first
and calling Grid.from_dense (what a converter without slabs does).

Each case runs in a fresh interpreter: import the libraries, reset the peak resident memory (VmHWM, through
/proc/self/clear_refs), convert, and report the peak above the memory held before, beside the volume's
values as a dense float32 array (voxels x 4 bytes), the memory the finished grid holds (resident memory with
the grid built, before writing) and the wall time.

| case       | what                                                                                  |
|------------|---------------------------------------------------------------------------------------|
| dicom      | convert a series (one file per slice), two passes (lowest value, then the grid)        |
| nifti_gz   | convert the same volume from a .nii.gz, streamed through gzip                          |
| dense      | the series read into one float32 array, then Grid.from_dense and write_vdb             |

    python tests/bench/import_memory_bench.py [--quick]     # prints the table
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

MiB = 1 << 20
ROOT = Path(__file__).resolve().parents[2]

CHILD = r"""
import json, sys, time
sys.path.insert(0, sys.argv[4])
import numpy as np
import pcvr_native as pn
import pydicom, nibabel
from pcvr_addon import volume_import

case, path, output = sys.argv[1], sys.argv[2], sys.argv[3]

def resident():
    return int(open('/proc/self/statm').read().split()[1]) * 4096

def peak():
    return next(int(line.split()[1]) * 1024 for line in open('/proc/self/status') if line.startswith('VmHWM'))

with open('/proc/self/clear_refs', 'w') as f:
    f.write('5')
before = resident()
start = time.perf_counter()
volume = volume_import.open_volume(path)
if case == "dense":
    values = np.concatenate(list(volume.read_slabs()))
    grid = pn.Grid.from_dense(values, volume.index_to_world, background=float(values.min()))
    grid.write_vdb(output, "density", metadata=volume.metadata())
    held = resident() - before
else:
    grid = volume_import.to_grid(volume)
    held = resident() - before
    grid.write_vdb(output, "density", metadata=volume.metadata())
seconds = time.perf_counter() - start
active = pn.list_grids(output)[0]["active_voxels"]
print(json.dumps({"peak_bytes": peak() - before, "held_bytes": held, "seconds": seconds, "active_voxels": active,
                  "voxels": int(np.prod(volume.shape))}))
"""


def ct_like(shape, rng):
    """int16 stored values of a CT: a noisy body (soft tissue, bone) in noisy air, -2048 padding outside the
    circular field of view (stored + intercept -1024 gives HU)."""
    n, rows, columns = shape
    y, x = np.mgrid[0:rows, 0:columns]
    r = np.hypot((y - rows / 2) / (rows / 2), (x - columns / 2) / (columns / 2))
    base = np.where(r < 0.6, 1064, 24).astype(np.int16)   # 40 HU tissue, -1000 HU air
    base[r < 0.15] = 1724                                   # 700 HU bone
    for s in range(n):
        noise = rng.normal(0, 20, size=(rows, columns)).astype(np.int16)
        slice_ = base + noise
        slice_[r > 1.0] = -1024                             # -2048 HU padding
        yield slice_


def write_scans(folder, shape, rng):
    sys.path.insert(0, str(ROOT / "tests"))
    import nibabel
    import scan_files as sf

    stored = np.stack(list(ct_like(shape, rng)))
    sf.dicom_series(str(folder / "dicom"), stored, pixel_spacing=(0.7, 0.7), step=(0, 0, 1.25), intercept=-1024.0)
    image = nibabel.Nifti1Image(np.transpose(stored, (2, 1, 0)), np.diag([-0.7, -0.7, 1.25, 1.0]))
    image.header.set_slope_inter(1.0, -1024.0)
    image.to_filename(str(folder / "ct.nii.gz"))
    return folder / "dicom", folder / "ct.nii.gz"


def measure(case, path, output):
    run = subprocess.run([sys.executable, "-c", CHILD, case, str(path), str(output), str(ROOT)],
                         capture_output=True, text=True, timeout=1800)
    if run.returncode != 0:
        raise RuntimeError(run.stderr)
    return json.loads(run.stdout)


def run(quick=False, log=print):
    shape = (48, 256, 256) if quick else (160, 512, 512)
    rng = np.random.default_rng(5)
    results = {"shape": shape, "cases": {}}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        log(f"writing a {shape[0]} x {shape[1]} x {shape[2]} DICOM series and .nii.gz")
        dicom, nifti = write_scans(folder, shape, rng)
        for case, path in (("dicom", dicom), ("nifti_gz", nifti), ("dense", dicom)):
            log(f"converting: {case}")
            result = measure(case, path, folder / f"{case}.vdb")
            result["values_bytes"] = result["voxels"] * 4
            result["peak_over_values"] = result["peak_bytes"] / result["values_bytes"]
            results["cases"][case] = result
    return results


def table(results):
    lines = [f"volume {' x '.join(map(str, results['shape']))}",
             "| case | values, dense float32 (MiB) | active voxels (M) | grid held (MiB) | peak above start (MiB) "
             "| peak / values | seconds |",
             "|------|---:|---:|---:|---:|---:|---:|"]
    for case, r in results["cases"].items():
        lines.append(f"| {case} | {r['values_bytes'] / MiB:.1f} | {r['active_voxels'] / 1e6:.1f} | "
                     f"{r['held_bytes'] / MiB:.1f} | {r['peak_bytes'] / MiB:.1f} | {r['peak_over_values']:.2f} "
                     f"| {r['seconds']:.1f} |")
    return "\n".join(lines)


if __name__ == "__main__":
    print(table(run(quick="--quick" in sys.argv, log=lambda message: print(message, file=sys.stderr))))
