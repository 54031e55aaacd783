# SPDX-License-Identifier: GPL-3.0-or-later

"""The viewport's progressive rendering: what to render next, when to cancel, what to re-use.

Plain Python, without bpy, gpu or pcvr_native, so that it runs and is tested headless: `ProgressiveRenderer`
runs the stages it is given (prepared_scene.prepare, native_render.render_raw, passes.finish) on a worker thread, and
`Schedule` decides which step comes next. Blender's side (viewport_session.py) hands in every change and draws
the latest image.

| change                                                  | prepare (grids, transfer functions) | render           | finish |
|---------------------------------------------------------|-------------------------------------|------------------|--------|
| view: orbit, zoom, camera, region size                  | re-used                             | restarts coarse  | again  |
| render inputs: a render setting, an object moved, a transfer function or light in shaded mode | again (grids from the cache) | restarts coarse | again |
| a crop box or clip plane moved                          | re-used (prepared_scene.Preparer)   | restarts coarse  | again  |
| display only: X-ray gain, transparent film, MIP colours | re-used                             | re-used          | again  |
| nothing that shows (selecting an object)                | -                                   | -                | -      |

Steps go from coarse to fine: each renders the region at 1/scale of its size in both directions (shaded and MIP
also with `sheet_spacing` times the sheet spacing; below full resolution, from the coarsest level of detail
whose voxels project to at most LEVEL_PIXELS of the step's pixels). A restart begins with the
finest step last measured to take at most FIRST_IMAGE_SECONDS in the same mode (the coarsest while none is
known), then refines, leaving out a step that took more than half as long as the next finer one (it would delay
that image more than it shows earlier), and stops after the finest step. A change cancels the running render
through the native cancel callback, except the first image of a restart (quick, or the coarsest there is): while
the view moves every frame, the first image must be allowed to finish, or no image would ever be shown
(tests/bench/viewport_bench.py, shaded CT phantom at 60 view changes a second on a busy 2-core machine: no image
at all while first images were cancelled too, 8 a second since they finish).
"""

import math
import threading
import time
from collections import Counter
from dataclasses import dataclass

# Within this time of a change the viewport should show a first image.
FIRST_IMAGE_SECONDS = 0.05

# A step that takes more than this share of the next finer step's time is left out.
SKIP_SHARE = 0.5


@dataclass(frozen=True)
class Step:
    scale: int                  # the image is 1/scale of the region's size in each direction
    sheet_spacing: float = 1.0  # times the sheet spacing of the settings (shaded and MIP)


# The sheet spacing grows with the pixels, so that a coarse shaded image costs fewer sheets too.
STEPS = (Step(8, 4.0), Step(4, 2.0), Step(2), Step(1))

# A step coarser than full resolution renders from the coarsest level of detail (Grid.level; for MIP, of maxima)
# whose voxels project to at most this many of its pixels where the grids are most magnified. Measured on the
# benchmark's CT phantom (4 views, against the full-resolution image averaged to the step's pixels): at the 1/8
# step level 1's voxels span up to 0.73 pixel; its shaded image is 1.4 dB nearer than level 0's (31.3 against
# 29.9 dB, whose 4x sheet spacing costs more) in 11 instead of 56 ms, its MIP 13% off instead of 22% in 10
# instead of 50 ms, its X-ray 1.4% off instead of 0.4% in 5 instead of 22 ms; voxels of 1.45 pixels (level 2 at
# 1/8, level 1 at 1/4) lost 0.7 and 2.3 dB shaded, were 22% and 10% off in MIP (level 0: 22% and 5.5%) and 11%
# and 5% in the X-ray.
LEVEL_PIXELS = 1.0


def step_level(step, grids_in_view):
    """The level of detail `step` renders from, or None at full resolution (the render settings' own level, as
    F12 renders). `grids_in_view()` -> (pixels per voxel of the step's image where the grids are most
    magnified, the fewest voxels any grid spans): levels stop at two voxels across, as automatic ones do."""
    if step.scale == 1:
        return None
    pixels_per_voxel, voxels_across = grids_in_view()
    level = 0
    if pixels_per_voxel <= 0:  # nothing in view
        return level
    while voxels_across >> (level + 1) >= 2 and pixels_per_voxel * 2 ** (level + 1) <= LEVEL_PIXELS:
        level += 1
    return level


@dataclass(frozen=True)
class Job:
    generation: int   # the restart it belongs to
    index: int        # into the schedule's steps
    first: bool       # the first step of its restart
    cost_key: object  # what its time depends on (see Schedule.restart)


class Schedule:
    """Which step to render next. Every change is a restart; a finished step leads to the next finer one."""

    def __init__(self, steps=STEPS, first_image_seconds=FIRST_IMAGE_SECONDS):
        self.steps = tuple(steps)
        self.first_image_seconds = first_image_seconds
        self.seconds = {}        # (cost key, step index) -> seconds of the last render of that step
        self.generation = 0
        self.pending = None      # index of the step to render next; None: nothing
        self._first = False
        self._cost_key = None

    def restart(self, cost_key=None):
        """Start again from the first step; `cost_key` names what the timings depend on (e.g. the mode)."""
        self.generation += 1
        self._cost_key = cost_key
        quick = [index for index in range(len(self.steps)) if self._quick(index)]
        self.pending = max(quick, default=0)
        self._first = True

    def take(self):
        """The next Job to render, or None."""
        if self.pending is None:
            return None
        job = Job(self.generation, self.pending, self._first, self._cost_key)
        self.pending, self._first = None, False
        return job

    def finished(self, job, seconds):
        """`job` rendered in `seconds`; a job of an earlier restart only teaches its timing."""
        self.seconds[(job.cost_key, job.index)] = seconds
        if job.generation == self.generation:
            self.pending = self._next(job.index)

    def failed(self, job):
        """`job` raised: stop until the next change."""
        if job.generation == self.generation:
            self.pending = None

    @staticmethod
    def may_cancel(job):
        """Whether a change may cancel the running `job`: all but a first image (see the module's docstring)."""
        return not job.first

    @property
    def done(self):
        return self.pending is None

    def _seconds(self, index):
        return self.seconds.get((self._cost_key, index), math.inf)

    def _quick(self, index):
        return self._seconds(index) <= self.first_image_seconds

    def _next(self, index):
        finest = len(self.steps) - 1
        if index >= finest:
            return None
        following = index + 1
        while following < finest and self._not_worth_it(following):
            following += 1
        return following

    def _not_worth_it(self, index):
        """A step measured to take more than SKIP_SHARE of the next finer one's time."""
        seconds = self._seconds(index)
        return not math.isinf(seconds) and seconds > SKIP_SHARE * self._seconds(index + 1)


@dataclass(frozen=True)
class _Rendered:
    """The latest render's results, kept to finish them again under another display."""
    inputs: object
    raw: object
    step: Step
    seconds: float
    view: object


@dataclass(frozen=True)
class ViewportImage:
    pixels: object    # float32 (height, width, 4), premultiplied scene-linear RGBA, row 0 on top
    serial: int       # a new number for every new image (drawing uploads a texture once per image)
    step: Step
    seconds: float    # render time
    view: object      # the view it shows


class ProgressiveRenderer:
    """Renders the latest (inputs, display, view) on a worker thread, coarse to fine (see the module).

    prepare(inputs) -> prepared              grids and native objects; raises on bad input
    render(prepared, view, step, cancel)     -> raw results, or None when `cancel` (a threading.Event) stopped it
    finish(display, raw)                     -> float32 (height, width, 4) premultiplied RGBA
    on_image()                               called on the worker thread after each new image
    cost_key(inputs)                         what render times depend on (timings are kept per key)

    update_scene, update_view, latest and stop are called from Blender's main thread.
    """

    def __init__(self, prepare, render, finish, on_image=lambda: None, cost_key=lambda inputs: None,
                 schedule=None):
        self._prepare, self._render, self._finish = prepare, render, finish
        self._on_image, self._cost_key = on_image, cost_key
        self.schedule = schedule or Schedule()
        self.counts = Counter()   # prepares, renders, cancelled, finishes, failures
        self._changed = threading.Condition()
        self._cancel = threading.Event()
        self._inputs = self._display = self._view = None
        self._prepared = None     # (inputs, PreparedScene)
        self._rendered = None     # _Rendered
        self._refinish = False
        self._running = None      # the Job being rendered
        self._working = False     # the worker is rendering or finishing
        self._image = None
        self._serial = 0
        self._error = None
        self._stopped = False
        self._thread = None

    # -- from the main thread

    def update_scene(self, inputs, display):
        """New readings of the scene: a render-input change restarts, a display change re-finishes the latest
        image, anything else is ignored. Returns what happened: "restart", "refinish" or None."""
        with self._changed:
            if inputs != self._inputs:
                self._inputs, self._display = inputs, display
                self._restart()
                return "restart"
            if display != self._display:
                self._display = display
                self._refinish = self._rendered is not None and self._rendered.inputs == inputs
                self._changed.notify_all()
                return "refinish"
            return None

    def update_view(self, view):
        """The view to render (engine's CameraView at full resolution); a new one restarts. None: nothing to
        render (e.g. the render border lies outside the region)."""
        with self._changed:
            if view == self._view:
                return False
            self._view = view
            self._restart()
            return True

    def latest(self):
        """The newest ViewportImage, or None."""
        with self._changed:
            return self._image

    @property
    def error(self):
        """Why the latest render failed, or None."""
        with self._changed:
            return self._error

    @property
    def running(self):
        """The Job being rendered, or None."""
        with self._changed:
            return self._running

    def prepared(self):
        """The PreparedScene of the current inputs once made, or None."""
        with self._changed:
            return self._prepared[1] if self._prepared and self._prepared[0] == self._inputs else None

    def wait_until_idle(self, timeout):
        """Wait until nothing is left to render or finish; False on timeout. For tests and scripts."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while not self._idle():
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return False
                self._changed.wait(remaining)
            return True

    def stop(self):
        """Cancel what runs and end the worker thread (waits for it, unless called from it)."""
        with self._changed:
            self._stopped = True
            self._cancel.set()
            self._changed.notify_all()
            thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join()

    # -- internals; _idle, _has_work and _restart expect the lock held

    def _idle(self):
        return self._stopped or not (self._working or self._has_work())

    def _has_work(self):
        return self._refinish or not (self.schedule.done or self._view is None or self._inputs is None)

    def _restart(self):
        """With the lock held."""
        if self._inputs is None or self._view is None:
            return
        if self._running is not None and self.schedule.may_cancel(self._running):
            self._cancel.set()
        self.schedule.restart(self._cost_key(self._inputs))
        self._error = None
        if self._thread is None and not self._stopped:
            self._thread = threading.Thread(target=self._work, name="PCVR viewport", daemon=True)
            self._thread.start()
        self._changed.notify_all()

    def _work(self):
        while True:
            with self._changed:
                while not self._stopped and not self._has_work():
                    self._changed.wait()
                if self._stopped:
                    return
                self._working = True
                if self._refinish:
                    self._refinish, job = False, None
                    rendered, display = self._rendered, self._display
                else:
                    job = self.schedule.take()
                    self._running = job
                    self._cancel.clear()
                    inputs, view = self._inputs, self._view
            try:
                if job is None:
                    self._publish(rendered, display)
                else:
                    self._render_job(job, inputs, view)
            finally:
                with self._changed:
                    self._working = False
                    self._changed.notify_all()

    def _render_job(self, job, inputs, view):
        step = self.schedule.steps[job.index]
        try:
            prepared = self._prepared_for(inputs)
            start = time.perf_counter()
            raw = self._render(prepared, view, step, self._cancel)
            seconds = time.perf_counter() - start
        except Exception as ex:  # noqa: BLE001 - whatever it is, the worker lives on and the viewport says it
            self._fail(ex, job)
            return
        with self._changed:
            self._running = None
            if raw is None:
                self.counts["cancelled"] += 1
                self._changed.notify_all()
                return
            self.counts["renders"] += 1
            self.schedule.finished(job, seconds)
            self._rendered = rendered = _Rendered(inputs, raw, step, seconds, view)
            display = self._display
        self._publish(rendered, display)

    def _prepared_for(self, inputs):
        """The PreparedScene of `inputs`, made again only when they changed."""
        with self._changed:
            if self._prepared is not None and self._prepared[0] == inputs:
                return self._prepared[1]
        prepared = self._prepare(inputs)
        with self._changed:
            self.counts["prepares"] += 1
            self._prepared = (inputs, prepared)
        return prepared

    def _publish(self, rendered, display):
        try:
            pixels = self._finish(display, rendered.raw)
        except Exception as ex:  # noqa: BLE001 - as in _render_job
            self._fail(ex)
            return
        with self._changed:
            self.counts["finishes"] += 1
            self._serial += 1
            self._image = ViewportImage(pixels, self._serial, rendered.step, rendered.seconds, rendered.view)
            self._changed.notify_all()
        self._on_image()

    def _fail(self, ex, job=None):
        with self._changed:
            self._running = None
            self.counts["failures"] += 1
            self._error = str(ex) or type(ex).__name__
            if job is not None:
                self.schedule.failed(job)
            self._changed.notify_all()
