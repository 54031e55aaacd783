"""Which peer renders fit the benchmark's time: shared by the peer child processes.

Views are rendered from the fewest pixels to the most. A configuration's time on the next view is
predicted from its last measured render scaled by the pixel count (peers trace every pixel); a
render predicted to take longer than the budget is skipped with that prediction as the reason.
"""


def pixels(view):
    return view["width"] * view["height"]


def ordered(views):
    return sorted(views.items(), key=lambda kv: pixels(kv[1]))


class Budget:
    def __init__(self, seconds):
        self.seconds = seconds
        self.last = {}  # config key -> (seconds, pixels)

    def skip_reason(self, config_key, view):
        if config_key not in self.last:
            return None
        t, px = self.last[config_key]
        predicted = t * pixels(view) / px
        if predicted > self.seconds:
            return f"predicted {predicted:.0f} s per render (over the {self.seconds:.0f} s budget)"
        return None

    def record(self, config_key, view, seconds):
        self.last[config_key] = (seconds, pixels(view))

    def runs(self, seconds, most=3):
        """Timed runs for a render that took `seconds` once: up to `most` while they fit a tenth of the budget."""
        return max(1, min(most, int(0.1 * self.seconds / max(seconds, 1e-9))))
