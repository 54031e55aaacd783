"""Peer renderers (Cycles, EEVEE, VTK) run in child processes, one per volume and runner.

A child gets a job file (the volume's .vdb, the views, the configurations, the budget; for shaded
renders the scene) and writes a result file with one record per configuration and view: render
times, the path of its image (.npy: the X-ray integral, or premultiplied RGBA), the camera's distance
from the view's matrices, or the reason it was skipped. A peer that cannot run at all (package
missing, no offscreen context, a crash) comes back as one reason for all its records, so the report
lists it as skipped instead of dropping it.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[2]
# (runner, mode) -> the child script; the job's "mode" picks it ("xray" when absent).
SCRIPTS = {(runner, mode): HERE / f"{runner}_{mode}.py" for runner in ("blender", "vtk") for mode in ("xray", "shaded")}
# EEVEE needs an OpenGL context: without a display, Mesa's EGL on its surfaceless platform (llvmpipe)
# gives it one. VTK picks its EGL render window the same way.
CHILD_ENV = {"EGL_PLATFORM": "surfaceless", "VTK_DEFAULT_OPENGL_WINDOW": "vtkEGLRenderWindow"}


def available(runner: str) -> str | None:
    """None when the runner's package imports, else why not."""
    module = {"blender": "bpy", "vtk": "vtk"}[runner]
    proc = subprocess.run([sys.executable, "-c", f"import {module}"], capture_output=True, text=True)
    if proc.returncode != 0:
        return f"`import {module}` failed: {(proc.stderr.strip().splitlines() or ['?'])[-1]}"
    return None


def run(runner: str, job: dict, workdir: Path, timeout_s: float, log) -> dict:
    """Run one child; {(config, view): record}. On failure every requested record carries the reason."""
    workdir.mkdir(parents=True, exist_ok=True)
    job = dict(job, repo=str(REPO), out_dir=str(workdir / "images"), result=str(workdir / "result.json"))
    job_path = workdir / "job.json"
    job_path.write_text(json.dumps(job))
    Path(job["result"]).unlink(missing_ok=True)
    wanted = [(c["key"], v) for c in job["configs"] for v in job["views"]]
    reason = available(runner)
    if reason is None:
        env = dict(os.environ, **CHILD_ENV)
        try:
            script = SCRIPTS[runner, job.get("mode", "xray")]
            proc = subprocess.run([sys.executable, str(script), str(job_path)], env=env,
                                  capture_output=True, text=True, timeout=timeout_s)
            (workdir / "child.log").write_text(proc.stdout + proc.stderr)
            for line in proc.stderr.splitlines():
                if line.startswith(f"[{'blender' if runner == 'blender' else 'vtk'} "):
                    log("    " + line)
            if proc.returncode != 0:
                tail = [ln for ln in proc.stderr.strip().splitlines() if ln.strip()][-3:]
                reason = f"child exited with status {proc.returncode}: {' / '.join(tail)[-300:]}"
        except subprocess.TimeoutExpired:
            reason = f"child ran past {timeout_s:.0f} s and was stopped"
    records = {}
    if Path(job["result"]).exists():
        for rec in json.loads(Path(job["result"]).read_text()):
            records[(rec["config"], rec["view"])] = rec
    for key in wanted:
        if key not in records:
            records[key] = {"config": key[0], "view": key[1], "skipped": reason or "not rendered"}
    return records
