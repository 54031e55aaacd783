"""Resources: a render that cannot fit its memory limit fails before allocating, saying what it
needs; the estimate it checks is close to what a render really takes; cancelling stops every stage
promptly, and repeated cancelled renders leak nothing.

Anything that measures a process's memory runs in a fresh interpreter (_io_helpers.run_python)."""

import json
import textwrap
import time

import numpy as np
import pytest

import pcvr_native as pn
from pcvr_native import phantoms

from _io_helpers import run_python
from stress_helpers import LONG, METHODS, measures_memory
from xray_helpers import CameraSpec, frame_ortho


# The child's peak resident set from the moment it is reset. (Not ru_maxrss: Linux carries it
# across exec, so a child of a pytest that has loaded Blender starts with Blender's peak.)
PEAK_RSS = """
def reset_peak():
    open('/proc/self/clear_refs', 'w').write('5')

def peak():
    for line in open('/proc/self/status'):
        if line.startswith('VmHWM:'):
            return int(line.split()[1]) * 1024
"""


@measures_memory
@pytest.mark.parametrize("method", METHODS)
def test_request_beyond_the_limit_fails_before_allocating(method):
    """30000 x 30000 pixels under a 64 MiB limit: MemoryError naming the size, what it needs and the
    limit, before anything is allocated (the peak resident set grows by less than 16 MiB)."""
    proc = run_python(PEAK_RSS + textwrap.dedent(f"""
        import numpy as np, pcvr_native as pn
        from pcvr_native import cameras, phantoms
        grid = phantoms.dense_volume(8, seed=1).grid()
        cam = pn.Camera(cameras.look_at((0, 0, 50), (0, 0, 0), (0, 1, 0)), cameras.ortho(-5, 5, -5, 5, 1, 100), 30000, 30000)
        pn.render_xray(grid, pn.Camera(cam.world_to_camera, cam.projection, 8, 8), method={method!r})  # warm up
        reset_peak()
        before = peak()
        try:
            pn.render_xray(grid, cam, method={method!r}, memory_limit=64 * 2 ** 20)
            print('RENDERED')
        except MemoryError as e:
            print('MemoryError:', e)
        print('PEAK_GROWTH', peak() - before)
    """))
    assert proc.returncode == 0, proc.stderr
    assert "MemoryError: render_xray of a 30000 x 30000 image needs about" in proc.stdout, proc.stdout
    assert "GiB" in proc.stdout and "may use only 64 MiB (memory_limit)" in proc.stdout, proc.stdout
    assert int(proc.stdout.split("PEAK_GROWTH")[1]) < 16 * 2 ** 20


def test_default_limit_is_the_available_memory():
    """Without memory_limit, the limit is what the machine has available (MemAvailable and any
    cgroup limit): the largest image a Camera allows, 65536^2 pixels with a splat grid per thread,
    needs more than any machine has."""
    available = pn.default_memory_limit()
    assert 0 < available < 2 ** 50
    grid = phantoms.dense_volume(8, seed=1).grid()
    spec = frame_ortho(phantoms.dense_volume(8, seed=1), 2.0)
    cam = pn.Camera(spec.world_to_camera, spec.projection, 65536, 65536)
    with pytest.raises(MemoryError, match=r"needs about \d+ GiB .*the memory this machine has available"):
        pn.render_xray(grid, cam, method="regular")


def test_bad_memory_limit():
    spec = frame_ortho(phantoms.dense_volume(8, seed=1), 2.0)
    with pytest.raises(ValueError, match="memory_limit"):
        pn.render_xray(phantoms.dense_volume(8, seed=1).grid(), spec.camera(), memory_limit=0)


@measures_memory
@pytest.mark.parametrize("method,magnification", [("regular", 100.0), ("pcvr", 200.0), ("exact", 100.0)])
def test_estimate_is_close_to_the_peak(method, magnification):
    """What the budget adds up (stats['memory_bytes']: the image, a splat grid or double image per
    thread plus their sum, exact's rays) against the growth of the peak resident set during the
    render, in a fresh process. Two voxels at opposite corners of a 16^3 box, 1800 to 3600 pixels
    square: large buffers, little splatting. The estimate is an upper bound within a factor of 2.5
    (threads that steal no work never allocate their grid)."""
    proc = run_python(PEAK_RSS + textwrap.dedent(f"""
        import json, numpy as np, pcvr_native as pn
        import sys; sys.path.insert(0, 'tests')
        from xray_helpers import frame_ortho
        values = np.zeros((16, 16, 16), np.float32)
        values[0, 0, 0] = values[-1, -1, -1] = 1.0
        grid = pn.Grid.from_dense(values, np.eye(4))
        cam = frame_ortho((values, np.eye(4)), {magnification}).camera()
        pn.render_xray(grid, pn.Camera(cam.world_to_camera, cam.projection, 4, 4), method={method!r})
        reset_peak()
        before = peak()
        stats = {{}}
        pn.render_xray(grid, cam, method={method!r}, stats=stats)
        after = peak()
        print(json.dumps([stats['memory_bytes'], after - before]))
    """))
    assert proc.returncode == 0, proc.stderr
    estimate, growth = json.loads(proc.stdout.splitlines()[-1])
    assert estimate > 32 * 2 ** 20, "the render is too small to measure"
    assert 0.4 * estimate <= growth <= 1.05 * estimate + 8 * 2 ** 20, f"estimate {estimate / 2**20:.0f} MiB, peak grew {growth / 2**20:.0f} MiB"


# ------------------------------------------------------------------------------------------------
# Cancelling

def stage_workloads():
    """Per stage: (grids, camera, method, threads, when), each stage taking 0.1-0.5 s on one core;
    `when(elapsed, fraction)` says the render has reached that stage (progress is polled every 20 ms)."""
    ph = phantoms.dense_volume(96 if LONG else 64, seed=2)
    grid = ph.grid()
    small = phantoms.dense_volume(8, seed=2)
    spec = frame_ortho(ph, 1.0)
    away = CameraSpec(np.diag([-1.0, 1.0, -1.0, 1.0]) @ spec.world_to_camera, spec.projection, spec.width, spec.height)
    return {
        # Every block of 3000 copies is planned, and culled: only the plan runs.
        "plan": ([grid] * 3000, away.camera(), "pcvr", lambda t, f: t > 0.05),
        "splat": (grid, frame_ortho(ph, 12.0 if LONG else 10.0).camera(), "regular", lambda t, f: 0.2 < f < 0.8),
        # A 7000^2 (make stress: 10000^2) image of a small volume: the post filter takes 50 (90) ms of it.
        "post-convolution": (small.grid(), frame_ortho(small, 900.0 if LONG else 630.0).camera(), "pcvr",
                             lambda t, f: f >= 0.97),
        "exact": (grid, frame_ortho(ph, 0.7).camera(), "exact", lambda t, f: 0.2 < f < 0.8),
    }


@pytest.fixture(scope="module")
def workloads():
    return stage_workloads()


@pytest.mark.parametrize("stage", ["plan", "splat", "post-convolution", "exact"])
def test_cancel_in_every_stage_returns_promptly(workloads, stage):
    """The cancel callable is polled every 20 ms and the workers check between small chunks (blocks,
    pixel rows): from the moment it first returns True the render is back within 0.15 s (measured
    10-40 ms), whatever stage it is in. The post filter runs at about a nanosecond per pixel, so a
    poll may also find it done: then the render must have finished as promptly. (Clearing new
    buffers is the one step not polled: the kernel clears about 1.5 GB/s here, then the splat starts.)"""
    grids, cam, method, reached = workloads[stage]
    requested = []
    start = time.perf_counter()
    fraction = [0.0]

    def cancel():
        if not requested and reached(time.perf_counter() - start, fraction[0]):
            requested.append(time.perf_counter())
        return bool(requested)

    outcome = "finished"
    try:
        pn.render_xray(grids, cam, method=method, threads=1, cancel=cancel, progress=lambda f: fraction.__setitem__(0, f))
    except pn.RenderCancelled:
        outcome = "cancelled"
    returned = time.perf_counter()
    assert requested, f"{stage}: the render ended before reaching the stage"
    if stage != "post-convolution":
        assert outcome == "cancelled", f"{stage}: finished {returned - requested[0]:.3f} s after the request"
    assert returned - requested[0] < 0.15, f"{stage}: returned {returned - requested[0]:.3f} s after the request"


@measures_memory
def test_repeated_cancelled_renders_leak_nothing():
    """Renders of every method cancelled at 40 different moments, in a fresh process: after the
    first round has warmed the allocators up, the resident set stays within 8 MiB (measured 0-2)."""
    rounds = 6 if LONG else 3
    proc = run_python(f"""
        import json, threading, time, pcvr_native as pn
        from pcvr_native import phantoms
        import sys; sys.path.insert(0, 'tests')
        from xray_helpers import frame_ortho
        def rss():
            return int(open('/proc/self/statm').read().split()[1]) * 4096
        ph = phantoms.dense_volume(48, seed=2)
        grid = ph.grid()
        work = [(grid, frame_ortho(ph, 6.0).camera(), 'regular'), (grid, frame_ortho(ph, 24.0).camera(), 'pcvr'),
                (grid, frame_ortho(ph, 0.5).camera(), 'exact'), (grid, frame_ortho(ph, 6.0).camera(), 'bilinear_spread')]
        full = []
        for g, cam, method in work:
            t0 = time.perf_counter(); pn.render_xray(g, cam, method=method, threads=1); full.append(time.perf_counter() - t0)
        samples = []
        for r in range({rounds}):
            for k in range(10):
                for (g, cam, method), seconds in zip(work, full):
                    event = threading.Event()
                    timer = threading.Timer(seconds * k / 10, event.set)
                    timer.start()
                    try:
                        pn.render_xray(g, cam, method=method, threads=1, cancel=event)
                    except pn.RenderCancelled:
                        pass
                    timer.cancel()
            samples.append(rss())
        print(json.dumps(samples))
    """, timeout=1200)
    assert proc.returncode == 0, proc.stderr
    samples = json.loads(proc.stdout.splitlines()[-1])
    growth = max(samples[1:]) - samples[0]
    assert growth < 8 * 2 ** 20, f"resident set after each round: {[s // 2 ** 20 for s in samples]} MiB"
