#!/usr/bin/env python3
"""PCVR benchmarks: time against error beside Cycles, EEVEE and VTK, the paper's analysis as figures,
a search of kernel pairs, and PCVR's own speed, memory and limits; writes docs/benchmarks.md.

    python tests/bench/run_benchmarks.py --output docs/benchmarks.md      # full run (make bench)
    python tests/bench/run_benchmarks.py --quick --output /tmp/b.md       # smoke run, about 2 minutes

| part        | module           | what                                                                    |
|-------------|------------------|-------------------------------------------------------------------------|
| comparison  | evidence.py      | methods and peers of methods.py on datasets.py through views.py          |
| shaded      | shaded.py        | the paper's Fig 10a, the perspective targets, VTK, Cycles and EEVEE     |
| figures     | figures.py       | the paper's Figs 4-7, 11, 12 and the aliasing measurement (docs/figures) |
| search      | kernel_search.py | splat kernel / post filter pairs, numpy prototype                       |
| throughput  | this file        | PCVR's own speed, memory and limits on large volumes (below)             |
| viewport    | viewport_bench.py | the rendered viewport at 1280 x 720: each step, latency, images/s moving |
| zoomed out  | minification_bench.py | time and error against magnification from 1/128 to 8, every method, and the sub-pixels chosen |
| magnification | magnification_curve.py | pcvr's time over magnification 1 to 8, orthographic and perspective, and 1/64 to 1/2 against integrating per pixel |
| passband    | passband_bench.py | error against analytic truth with and without the passband compensation, the end-on column's mass, X-ray time of both |
| big volumes | big_volume_bench.py | memory and time of a 384^3 X-ray read whole, streamed and zoomed out |
| shaded levels | shaded_levels.py | shaded and MIP error and time per level of detail, 1/2 to 1/32 |
| batches     | batch_bench.py   | frames/s and DRRs/s in one process and on 1 and 2 Dask workers, overheads, N machines |
| real volumes | ct_head.py      | shaded rendering of a CT head and two MR heads (shaded_volumes.py) with five transfer functions against VTK, and slicing rings |
| cut open    | clipping_bench.py | X-ray and shaded time and error of the CT head whole, cropped to half, cut by a plane |
| DRR         | drr_bench.py     | cone-beam DRRs of the CT head beside plastimatch and RTK: time, DRRs/s, error against a ray march |
| shadows     | shadows_bench.py | shaded time with and without shadows, CT phantom and CT head, against the ray caster's shadow rays |
| materials   | materials_bench.py | smoke, fire (Quick Smoke / Quick Fire) and a shadowed CT head by PCVR and Cycles in Blender: time, PSNR |

Throughput: for each volume (a dense and a sparse cloud phantom at 128^3 and 256^3) and each magnification
(1, 2, 4, 8 pixels per voxel) one oblique orthographic camera frames the whole volume, and:

| step     | what                                                                                     |
|----------|------------------------------------------------------------------------------------------|
| exact    | the reference, `method="exact"` at `pixel_step=7` (7 is co-prime with every stride used,  |
|          | so the sampled pixels cover all subgrid phases)                                           |
| timing   | every method once per repetition, in an order rotated each repetition, so that noise from |
|          | other work on the machine hits all methods alike; median wall time per method            |
| accuracy | each method's image at pixels [::7, ::7] against the exact samples: relative RMSE, PSNR   |
| memory   | each configuration once more in a fresh child process: peak resident memory of the render |
|          | (VmHWM reset through /proc/self/clear_refs after the grid is built)                      |
| limits   | 256^3 only: the same camera on a grid with one voxel per 8^3 block, which leaves the work |
|          | that scales with the image (buffers, post-convolution, reduction); and threads=1         |
| persp.   | the largest dense volume through a pinhole camera (4 pixels per voxel at its centre):    |
|          | timing and accuracy as above, with a depth band per stride                                |

Then the speed-of-light micro-benchmarks (speed_of_light.py) and the report with two plots under
docs/img/. Raw numbers go to out/bench/results.json. Progress goes to stderr.
"""

from __future__ import annotations

import argparse
import datetime
import gc
import importlib
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
sys.path.insert(0, str(HERE))

import speed_of_light as sol  # noqa: E402
import views  # noqa: E402
from evidence import error_metrics  # noqa: E402

PIXEL_STEP = 7
KERNEL = "gauss1.4"

# (key, label, method, post_filter)
METHODS = [
    ("regular", "regular", "regular", "bilinear"),
    ("pcvr_bilinear", "pcvr + bilinear", "pcvr", "bilinear"),
    ("pcvr_gauss", "pcvr + gauss1.4", "pcvr", "gauss1.4"),
    ("bilinear_spread", "bilinear spread", "bilinear_spread", "bilinear"),
]
METHOD_KEYS = [m[0] for m in METHODS]


# The parts with a run(quick, log) of their own, in the order they run: (args flag and results key, module,
# what the log says).
STANDALONE_PARTS = [
    ("viewport", "viewport_bench", "rendered viewport"),
    ("minification", "minification_bench", "time and error against magnification"),
    ("magnification_curve", "magnification_curve", "X-ray speed over magnification"),
    ("passband", "passband_bench", "passband compensation: error against the truth, mass, time"),
    ("shaded_levels", "shaded_levels", "shaded and MIP levels of detail"),
    ("big_volume", "big_volume_bench", "big volumes"),
    ("batch", "batch_bench", "batches over Dask"),
    ("ct_head", "ct_head", "shaded rendering of real volumes against VTK"),
    ("clipping", "clipping_bench", "cut open: crop boxes and clip planes"),
    ("drr", "drr_bench", "DRRs beside plastimatch and RTK"),
    ("shadows", "shadows_bench", "shadows: cost and accuracy"),
    ("materials", "materials_bench", "Blender's volume materials beside Cycles"),
]


def log(msg: str) -> None:
    print(f"[bench {time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


# ------------------------------------------------------------------------------------------------
# Volumes and cameras

def make_volume(kind: str, n: int):
    from pcvr_native import phantoms
    if kind == "dense":
        return phantoms.dense_volume(n, seed=1)
    if kind == "sparse":
        return phantoms.sparse_cloud(n, seed=2)
    raise ValueError(kind)


def lattice_volume(n: int, index_to_world):
    """One voxel at the centre of every 8^3 block: every block (and image tile) touched, ~no splats."""
    values = np.zeros((n, n, n), dtype=np.float32)
    values[4::8, 4::8, 4::8] = 1.0
    return values, index_to_world


def camera_spec(shape, index_to_world, magnification: float) -> dict:
    """The oblique orthographic view of views.py as the matrices pcvr_native takes, plus the subgrid
    node coordinates per index step (for the C splat harness): camera xy per index / node size."""
    view = views.oblique(shape, index_to_world, magnification)
    w2c, proj = views.matrices(view)
    jac = w2c[:2, :3] @ np.asarray(index_to_world, dtype=np.float64)[:3, :3]
    node = view["ortho_scale"] / max(view["width"], view["height"]) * magnification
    return {"world_to_camera": w2c.tolist(), "projection": proj.tolist(), "width": view["width"],
            "height": view["height"], "node_gx": (jac[0] / node).tolist(), "node_gy": (-jac[1] / node).tolist()}


def perspective_spec(shape, index_to_world, magnification: float) -> dict:
    """The perspective view of views.py as the matrices pcvr_native takes."""
    view = views.perspective(shape, index_to_world, magnification)
    w2c, proj = views.matrices(view)
    return {"world_to_camera": w2c.tolist(), "projection": proj.tolist(), "width": view["width"],
            "height": view["height"]}


def make_camera(spec: dict):
    import pcvr_native as pn
    return pn.Camera(np.asarray(spec["world_to_camera"]), np.asarray(spec["projection"]), spec["width"], spec["height"])


def tiny_camera(spec: dict):
    """A 16 x 16 corner of `spec`'s view: cheap, but it makes the grid build its block cache."""
    import pcvr_native as pn
    p = np.asarray(spec["projection"], dtype=np.float64).copy()
    s = np.diag([spec["width"] / 16.0, spec["height"] / 16.0, 1.0, 1.0])
    return pn.Camera(np.asarray(spec["world_to_camera"]), s @ p, 16, 16)


# ------------------------------------------------------------------------------------------------
# Rendering and measurement helpers

def render(grid, cam, method: str, post: str, threads: int, **kw):
    import pcvr_native as pn
    stats: dict = {}
    c0 = time.process_time()
    t0 = time.perf_counter()
    img = pn.render_xray(grid, cam, method, KERNEL, post, 0, threads, stats=stats, **kw)
    stats["wall_s"] = time.perf_counter() - t0
    stats["cpu_s"] = time.process_time() - c0  # all threads of this process
    return img, stats["wall_s"], stats


def proc_status_kb(field: str) -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    return -1


def reset_peak_rss() -> bool:
    """Reset VmHWM to the current RSS (Linux >= 4.0); False where the kernel refuses."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


def child_memory(job_path: str) -> int:
    """Child process: build the grid, then report the peak memory of one render (JSON on stdout)."""
    import pcvr_native as pn
    job = json.loads(Path(job_path).read_text())
    values = np.load(job["values"])
    xf = np.asarray(job["index_to_world"])
    grid = pn.Grid.from_dense(values, xf, 0.0)
    del values
    gc.collect()
    spec = job["camera"]
    pn.render_xray(grid, tiny_camera(spec), "pcvr", KERNEL, "bilinear", 0, job["threads"])  # block cache
    gc.collect()
    base_kb = proc_status_kb("VmRSS")
    reset_ok = reset_peak_rss()
    img = pn.render_xray(grid, make_camera(spec), job["method"], KERNEL, job["post"], 0, job["threads"])
    peak_kb = proc_status_kb("VmHWM")
    maxrss_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    del img
    print(json.dumps({"base_mb": base_kb / 1024, "peak_mb": (peak_kb if reset_ok else maxrss_kb) / 1024,
                      "extra_mb": ((peak_kb if reset_ok else maxrss_kb) - base_kb) / 1024,
                      "maxrss_mb": maxrss_kb / 1024, "hwm_reset": reset_ok}))
    return 0


def measure_memory(values_path: Path, xf, spec: dict, method: str, post: str, threads: int, workdir: Path) -> dict:
    job = {"values": str(values_path), "index_to_world": np.asarray(xf).tolist(), "camera": spec, "method": method,
           "post": post, "threads": threads}
    job_path = workdir / "memory_job.json"
    job_path.write_text(json.dumps(job))
    proc = subprocess.run([sys.executable, __file__, "--child-memory", str(job_path)], capture_output=True, text=True)
    if proc.returncode != 0:
        return {"error": (proc.stderr or proc.stdout).strip()[-500:] or f"exit status {proc.returncode}"}
    return json.loads(proc.stdout.strip().splitlines()[-1])


# ------------------------------------------------------------------------------------------------
# The benchmark of one volume

def plan_reps(first_times: dict, args) -> dict:
    """Runs per method after one interleaved repetition: as many as fit the per-configuration budget,
    between --min-reps and --reps; a method slower than --slow alone may drop to 1 run."""
    share = args.budget / len(first_times)
    reps = {}
    for key, t in first_times.items():
        k = int(share // max(t, 1e-9))
        lo = 1 if t > args.slow else args.min_reps
        reps[key] = max(lo, min(args.reps, k))
    return reps


def measure_config(grid, spec: dict, active: int, args, label: str) -> dict:
    """Every method on one camera: the exact reference (every PIXEL_STEP-th pixel), then timed runs of
    the methods in an order rotated every repetition, with their errors against exact."""
    cam = make_camera(spec)
    cfg = {"width": spec["width"], "height": spec["height"], "methods": {}}
    exact, t_exact, _ = render(grid, cam, "exact", "bilinear", args.threads, pixel_step=PIXEL_STEP)
    cfg["exact_s"] = t_exact
    exact = np.asarray(exact, dtype=np.float64)
    times = {k: [] for k in METHOD_KEYS}
    reps = None
    rep = 0
    while True:
        order = METHOD_KEYS[rep % len(METHODS):] + METHOD_KEYS[:rep % len(METHODS)]
        ran = False
        for key in order:
            if reps is not None and len(times[key]) >= reps[key]:
                continue
            _, _, method, post = METHODS[METHOD_KEYS.index(key)]
            img, t, stats = render(grid, cam, method, post, args.threads)
            times[key].append(t)
            ran = True
            if rep == 0:
                cfg["methods"][key] = {"stride": stats.get("stride"), "strides": stats.get("strides"),
                                       "voxels": stats.get("voxels"), "native_seconds": [], "cpu_seconds": [],
                                       **error_metrics(img, exact)}
                if img.shape != (spec["height"], spec["width"]):
                    raise RuntimeError(f"{method}: image {img.shape}, camera {spec['height']}x{spec['width']}")
            cfg["methods"][key]["native_seconds"].append(stats.get("seconds"))
            cfg["methods"][key]["cpu_seconds"].append(stats["cpu_s"])
            del img
        if not ran:
            break
        if rep == 0:
            reps = plan_reps({k: v[0] for k, v in times.items()}, args)
        rep += 1
    for key in METHOD_KEYS:
        m = cfg["methods"][key]
        m["times"] = times[key]
        m["runs"] = len(times[key])
        m["median_s"] = statistics.median(times[key])
        m["mvox_per_s"] = active / m["median_s"] / 1e6
        m["cores_busy"] = statistics.median(c / t for c, t in zip(m["cpu_seconds"], times[key]))
    t_reg = cfg["methods"]["regular"]["median_s"]
    for key in METHOD_KEYS:
        cfg["methods"][key]["speedup"] = t_reg / cfg["methods"][key]["median_s"]
    log(f"  {label}: " + ", ".join(
        f"{k} {1e3 * cfg['methods'][k]['median_s']:.0f} ms x{cfg['methods'][k]['runs']} "
        f"({cfg['methods'][k]['speedup']:.1f}x, {100 * cfg['methods'][k]['rel_rmse']:.2f}%)" for k in METHOD_KEYS))
    return cfg


def bench_volume(kind: str, n: int, args, workdir: Path, results: dict) -> None:
    import pcvr_native as pn
    name = f"{kind} {n}^3"
    log(f"volume {name}: generating")
    t0 = time.perf_counter()
    phantom = make_volume(kind, n)
    values, xf = np.ascontiguousarray(phantom.values, dtype=np.float32), np.asarray(phantom.index_to_world)
    gen_s = time.perf_counter() - t0
    values_path = workdir / f"{kind}_{n}.npy"
    np.save(values_path, values)
    t0 = time.perf_counter()
    grid = pn.Grid.from_dense(values, xf, 0.0)
    build_s = time.perf_counter() - t0
    active = int(grid.active_voxel_count)
    del values
    vol = {"kind": kind, "n": n, "active_voxels": active, "fill": active / n ** 3, "generate_s": gen_s,
           "grid_build_s": build_s, "configs": {}}
    results["volumes"].append(vol)
    spec1 = camera_spec((n, n, n), xf, 1.0)
    t0 = time.perf_counter()
    pn.render_xray(grid, tiny_camera(spec1), "pcvr", KERNEL, "bilinear", 0, args.threads)
    vol["block_cache_s"] = time.perf_counter() - t0
    log(f"volume {name}: {active} active voxels ({100 * active / n ** 3:.1f}%), grid built in {build_s:.2f} s")

    for mag in args.magnifications:
        spec = camera_spec((n, n, n), xf, float(mag))
        log(f"  m={mag}: {spec['width']}x{spec['height']} pixels; exact reference at pixel_step={PIXEL_STEP}")
        cfg = vol["configs"][str(mag)] = measure_config(grid, spec, active, args, f"m={mag}")
        cfg["magnification"] = mag
        if not args.no_memory:
            for key, _, method, post in METHODS:
                cfg["methods"][key]["memory"] = measure_memory(values_path, xf, spec, method, post, args.threads, workdir)
            log("  m=%d memory: " % mag + ", ".join(
                f"{k} {cfg['methods'][k]['memory'].get('extra_mb', float('nan')):.0f} MB" for k in METHOD_KEYS))

    if n == max(args.sizes) and kind == "dense" and args.perspective:
        spec = perspective_spec((n, n, n), xf, views.PERSPECTIVE_MAGNIFICATION)
        low, high = pn.effective_magnification(grid, make_camera(spec))
        log(f"  perspective: {spec['width']}x{spec['height']} pixels, {low:.1f} to {high:.1f} pixels per voxel")
        cfg = vol["perspective"] = measure_config(grid, spec, active, args, "perspective")
        cfg.update(magnification=views.PERSPECTIVE_MAGNIFICATION, min_magnification=low, max_magnification=high,
                   distance_diagonals=views.PERSPECTIVE_DISTANCE)

    values_path.unlink(missing_ok=True)  # only the memory children needed it
    if n == max(args.sizes) and kind == "dense":
        limits(grid, xf, n, vol, args)
    del grid
    gc.collect()


def limits(grid, xf, n: int, vol: dict, args) -> None:
    """What the time is spent on: image-sized work (lattice grid) and scaling with threads."""
    import pcvr_native as pn
    lv, lxf = lattice_volume(n, xf)
    lattice = pn.Grid.from_dense(lv, lxf, 0.0)
    del lv
    out = vol["limits"] = {"lattice_voxels": int(lattice.active_voxel_count), "configs": {}, "thp": read_thp()}
    for mag in args.magnifications:
        spec = camera_spec((n, n, n), xf, float(mag))
        cam = make_camera(spec)
        pn.render_xray(lattice, tiny_camera(spec), "pcvr", KERNEL, "bilinear", 0, args.threads)
        row = out["configs"][str(mag)] = {}
        for key, _, method, post in METHODS:
            ts = []
            for _ in range(max(1, args.limit_reps)):
                _, t, _ = render(lattice, cam, method, post, args.threads)
                ts.append(t)
            row[key] = statistics.median(ts)
        # First-touch page faults of the render's fresh buffers, and the kernel time they cost.
        r0 = resource.getrusage(resource.RUSAGE_SELF)
        _, t, _ = render(grid, cam, "pcvr", "bilinear", args.threads)
        r1 = resource.getrusage(resource.RUSAGE_SELF)
        row["pcvr_fault_mb"] = (r1.ru_minflt - r0.ru_minflt) * resource.getpagesize() / 2 ** 20
        row["pcvr_sys_s"] = r1.ru_stime - r0.ru_stime
        row["pcvr_fault_wall_s"] = t
        # One thread against all: the parallel efficiency of pcvr.
        if (os.cpu_count() or 1) > 1 and args.threads != 1:
            t1 = [render(grid, cam, "pcvr", "bilinear", 1)[1] for _ in range(max(1, args.limit_reps))]
            tn = [render(grid, cam, "pcvr", "bilinear", args.threads)[1] for _ in range(max(1, args.limit_reps))]
            row["pcvr_1thread"] = statistics.median(t1)
            row["pcvr_all_threads"] = statistics.median(tn)
        log(f"  limits m={mag}: image-sized work " + ", ".join(f"{k} {1e3 * row[k]:.0f} ms" for k in METHOD_KEYS)
            + (f"; pcvr 1 thread {1e3 * row['pcvr_1thread']:.0f} ms vs {1e3 * row['pcvr_all_threads']:.0f} ms"
               if "pcvr_1thread" in row else ""))


def read_thp() -> str:
    try:
        text = Path("/sys/kernel/mm/transparent_hugepage/enabled").read_text()
        return text[text.index("[") + 1:text.index("]")]
    except (OSError, ValueError):
        return "?"


# ------------------------------------------------------------------------------------------------
# Machine information

def machine_info() -> dict:
    info = {"python": platform.python_version(), "numpy": np.__version__, "platform": platform.platform()}
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, check=True).stdout
        fields = dict(line.split(":", 1) for line in out.splitlines() if ":" in line)
        fields = {k.strip(): v.strip() for k, v in fields.items()}
        info["cpu"] = fields.get("Model name", "?")
        info["cpus"] = fields.get("CPU(s)", "?")
        info["threads_per_core"] = fields.get("Thread(s) per core", "?")
        info["hypervisor"] = fields.get("Hypervisor vendor", "")
        flags = fields.get("Flags", "").split()
        info["simd"] = [f for f in ("avx2", "fma", "avx512f", "avx512bw", "avx512vl") if f in flags]
        info["l2"] = fields.get("L2 cache", "?")
        info["l3"] = fields.get("L3 cache", "?")
    except (OSError, subprocess.CalledProcessError):
        info["cpu"] = platform.processor()
    try:
        info["memory_gb"] = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2 ** 30
    except (ValueError, OSError):
        pass
    try:
        rev = subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], cwd=REPO, capture_output=True, text=True).stdout.strip()
        # The pages and plots this run rewrites do not count as changes to what is measured.
        generated = [":!docs/benchmarks.md", ":!docs/img", ":!docs/figures"]
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", ".", *generated],
                               cwd=REPO, capture_output=True, text=True).stdout.strip()
        info["commit"] = rev + (" (with uncommitted changes)" if dirty else "")
    except OSError:
        info["commit"] = "?"
    try:
        cc = subprocess.run([os.environ.get("CC", "cc"), "--version"], capture_output=True, text=True).stdout.splitlines()
        info["cc"] = cc[0] if cc else "?"
    except OSError:
        info["cc"] = "?"
    try:
        import pcvr_native as pn
        info["pcvr_native"] = str(Path(pn.__file__).parent)
        so = sorted(Path(pn.__file__).parent.glob("_pcvr*.so"))
        if so:
            info["pcvr_native_built"] = datetime.datetime.fromtimestamp(so[0].stat().st_mtime).astimezone().isoformat(
                timespec="seconds")
    except ImportError:
        pass
    return info


# ------------------------------------------------------------------------------------------------

def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--output", default=str(REPO / "docs" / "benchmarks.md"), help="markdown report to write")
    p.add_argument("--quick", action="store_true", help="smoke run: 64^3 and 96^3, magnifications 1, 2, 4, one repetition")
    p.add_argument("--sizes", type=int, nargs="+", help="volume edge lengths (default 128 256)")
    p.add_argument("--kinds", nargs="+", default=["dense", "sparse"], choices=["dense", "sparse"])
    p.add_argument("--magnifications", type=int, nargs="+", help="pixels per voxel (default 1 2 4 8)")
    p.add_argument("--reps", type=int, help="most timed runs per method and configuration (default 7)")
    p.add_argument("--min-reps", type=int, help="fewest runs per method unless it is slower than --slow (default 3)")
    p.add_argument("--budget", type=float, help="seconds of timed renders per configuration (default 40)")
    p.add_argument("--slow", type=float, default=60.0, help="a method slower than this (s) may run only once")
    p.add_argument("--limit-reps", type=int, help="runs per measurement in the 'what limits us' part (default 3)")
    p.add_argument("--threads", type=int, default=0, help="render threads (0 = all cores)")
    p.add_argument("--no-memory", action="store_true", help="skip the per-configuration memory children")
    p.add_argument("--no-sol", action="store_true", help="skip the speed-of-light micro-benchmarks")
    p.add_argument("--no-perspective", dest="perspective", action="store_false",
                   help="skip the perspective view of the largest dense volume")
    p.add_argument("--results", default=str(REPO / "out" / "bench" / "results.json"), help="raw results (JSON)")
    p.add_argument("--from-results", help="only write the report from a results.json of an earlier run")
    p.add_argument("--child-memory", help=argparse.SUPPRESS)
    p.add_argument("--datasets", nargs="*", help="data sets of the X-ray comparison (default: blobs ct ml "
                   "sparse; --quick: blobs ct; none given: skip it)")
    p.add_argument("--skip-peers", nargs="*", default=[], help="method keys (methods.py) not to run")
    p.add_argument("--peer-timeout", type=float, default=900.0, help="seconds one peer child may run")
    p.add_argument("--no-shaded", dest="shaded", action="store_false",
                   help="skip the shaded comparison (Fig 10a, perspective targets, shaded peers)")
    p.add_argument("--no-figures", dest="figures", action="store_false", help="skip the paper's figures")
    p.add_argument("--no-search", dest="search", action="store_false", help="skip the kernel search")
    p.add_argument("--no-throughput", dest="throughput", action="store_false",
                   help="skip PCVR's own throughput, memory and limits")
    p.add_argument("--no-minification", dest="minification", action="store_false",
                   help="skip time and error against magnification")
    p.add_argument("--no-viewport", dest="viewport", action="store_false",
                   help="skip the rendered viewport's speed")
    p.add_argument("--no-magnification-curve", dest="magnification_curve", action="store_false",
                   help="skip pcvr's time over magnification")
    p.add_argument("--no-passband", dest="passband", action="store_false",
                   help="skip the passband compensation's error, mass and time")
    p.add_argument("--no-big-volume", dest="big_volume", action="store_false",
                   help="skip the big volume's memory and time, read whole and streamed")
    p.add_argument("--no-shaded-levels", dest="shaded_levels", action="store_false",
                   help="skip shaded and MIP error and time per level of detail")
    p.add_argument("--no-batch", dest="batch", action="store_false",
                   help="skip frames/s and DRRs/s of batches in one process and on Dask workers")
    p.add_argument("--no-ct-head", dest="ct_head", action="store_false",
                   help="skip the real volumes (a CT head, two MR heads) against VTK")
    p.add_argument("--no-clipping", dest="clipping", action="store_false",
                   help="skip the CT head whole, cropped and cut by a plane")
    p.add_argument("--no-drr", dest="drr", action="store_false",
                   help="skip cone-beam DRRs beside plastimatch and RTK")
    p.add_argument("--no-shadows", dest="shadows", action="store_false",
                   help="skip the cost and accuracy of shadows")
    p.add_argument("--no-materials", dest="materials", action="store_false",
                   help="skip smoke, fire and the CT head beside Cycles in Blender")
    args = p.parse_args(argv)
    args.skip_peers = set(args.skip_peers)
    # Full images of the CT phantom at m=4 stay on disk for the side-by-side figure.
    args.keep_images = {"ct": {"m4"}}
    if args.quick:
        defaults = {"datasets": ["blobs", "ct"], "sizes": [64], "magnifications": [1, 2, 4, 8], "reps": 1, "min_reps": 1, "budget": 1.0,
                    "limit_reps": 1}
    else:
        defaults = {"datasets": ["blobs", "ct", "ml", "sparse"], "sizes": [256], "magnifications": [1, 2, 4, 8], "reps": 7, "min_reps": 3, "budget": 12.0,
                    "limit_reps": 3}
    for k, v in defaults.items():
        if getattr(args, k) is None:
            setattr(args, k, v)
    return args


def run_evidence(args, results: dict, results_path: Path, output: Path) -> None:
    """The comparisons (X-ray, shaded), the figures and the kernel search (the parts a reader judges
    PCVR by)."""
    import evidence
    import figures
    import kernel_search
    workdir = results_path.parent
    fig_dir = output.parent / "figures"
    if args.datasets:
        log("X-ray comparison: " + ", ".join(args.datasets))
        results["xray"] = evidence.run(args, workdir / "evidence", log)
        results_path.write_text(json.dumps(results, indent=1, default=float))
    if args.shaded:
        import shaded
        log("shaded: the paper's Fig 10a, the perspective targets, VTK, Cycles and EEVEE")
        results["shaded"] = shaded.run(args, workdir / "shaded", log)
        results_path.write_text(json.dumps(results, indent=1, default=float))
    if args.figures:
        results["figures"] = figures.run(fig_dir, args.quick, log)
        results_path.write_text(json.dumps(results, indent=1, default=float))
    if args.search:
        results["kernel_search"] = kernel_search.run(args.quick, log)
        results_path.write_text(json.dumps(results, indent=1, default=float))


def main(argv=None) -> int:
    args = parse_args(argv)
    if args.child_memory:
        return child_memory(args.child_memory)
    output = Path(args.output)
    results_path = Path(args.results)
    import report

    if args.from_results:
        results = json.loads(Path(args.from_results).read_text())
        report.write(results, output)
        log(f"wrote {output}")
        return 0

    try:
        import pcvr_native as pn
        pn.render_xray, pn.Grid  # noqa: B018
    except (ImportError, AttributeError) as e:
        log(f"pcvr_native is not importable ({e}); run `make native` first")
        return 2

    workdir = results_path.parent
    workdir.mkdir(parents=True, exist_ok=True)
    started = time.time()
    results = {"quick": args.quick, "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
               "machine": machine_info(), "settings": {
                   "sizes": args.sizes, "kinds": args.kinds, "magnifications": args.magnifications, "reps": args.reps,
                   "min_reps": args.min_reps, "budget_s": args.budget, "slow_s": args.slow, "threads": args.threads,
                   "pixel_step": PIXEL_STEP, "kernel": KERNEL, "view_direction": views.VIEW_DIRECTION, "view_up": views.VIEW_UP,
                   "methods": METHODS},
               "load_before": os.getloadavg(), "volumes": []}
    log(f"machine: {results['machine'].get('cpu')}, {results['machine'].get('cpus')} CPUs, "
        f"load {results['load_before'][0]:.2f}")

    run_evidence(args, results, results_path, output)
    for flag, module, what in STANDALONE_PARTS:
        if getattr(args, flag):
            log(what)
            results[flag] = importlib.import_module(module).run(args.quick, log)
            results_path.write_text(json.dumps(results, indent=1, default=float))
    for n in args.sizes if args.throughput else []:
        for kind in args.kinds:
            bench_volume(kind, n, args, workdir, results)
            results_path.write_text(json.dumps(results, indent=1, default=float))

    if not args.no_sol and args.throughput:
        log("speed of light: compiling and running sol_kernels.c")
        n_sol = max(args.sizes)
        spec = camera_spec((n_sol,) * 3, np.eye(4), 1.0)
        try:
            m = sol.measure(workdir, n=n_sol, gx=spec["node_gx"], gy=spec["node_gy"], log=log)
            results["sol"] = {"tests": [rec for rec in m["tests"].values()], "threads": m["threads"], "n": n_sol}
        except (RuntimeError, OSError, subprocess.CalledProcessError) as e:
            log(f"speed of light failed: {e}")
            results["sol"] = {"error": str(e)}

    results["load_after"] = os.getloadavg()
    results["total_s"] = time.time() - started
    results_path.write_text(json.dumps(results, indent=1, default=float))
    report.write(results, output)
    log(f"wrote {output} and {results_path} in {results['total_s'] / 60:.1f} min")
    return 0


if __name__ == "__main__":
    sys.exit(main())
