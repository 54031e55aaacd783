# SPDX-License-Identifier: GPL-3.0-or-later

"""The progress bar of a batch: images done, images per second and the time left, on one line.

On a terminal the line is redrawn in place (at most every INTERVAL seconds); into a file or pipe a line is
printed every tenth of the batch, so that logs stay short.
"""

import sys
import time


def format_duration(seconds):
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    minutes, seconds = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{seconds:02d}" if hours else f"{minutes}:{seconds:02d}"


class ProgressBar:
    INTERVAL = 0.2  # seconds between redraws on a terminal
    WIDTH = 30

    def __init__(self, total, stream=None, clock=time.monotonic):
        self.total, self.stream, self.clock = total, stream or sys.stderr, clock
        self.done = 0
        self.start = clock()
        self.shown_at = None
        self.shown_tenth = -1
        self.live = hasattr(self.stream, "isatty") and self.stream.isatty()

    def line(self):
        """"[#########.....] 12/40 images | 3.1/s | 0:09 left" (the rate and time left once one is done)."""
        filled = self.WIDTH * self.done // max(self.total, 1)
        text = f"[{'#' * filled}{'.' * (self.WIDTH - filled)}] {self.done}/{self.total} images"
        elapsed = self.clock() - self.start
        if 0 < self.done < self.total and elapsed > 0:
            rate = self.done / elapsed
            text += f" | {rate:.2f}/s | {format_duration((self.total - self.done) / rate)} left"
        elif self.done >= self.total:
            text += f" | {format_duration(elapsed)}"
        return text

    def advance(self, count=1):
        self.done += count
        now = self.clock()
        if self.live:
            if self.done >= self.total or self.shown_at is None or now - self.shown_at >= self.INTERVAL:
                self.stream.write("\r" + self.line() + ("\n" if self.done >= self.total else ""))
                self.stream.flush()
                self.shown_at = now
            return
        tenth = 10 * self.done // max(self.total, 1)
        if tenth != self.shown_tenth:
            self.shown_tenth = tenth
            self.stream.write(self.line() + "\n")
            self.stream.flush()
