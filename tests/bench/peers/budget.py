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

    def repeat(self, render, most=3):
        """Timed runs of `render` (returning (seconds, result)): one, and more up to `most` while they fit
        a tenth of the budget. Returns the list of seconds and the last result."""
        seconds, result = render()
        times = [seconds]
        while len(times) < max(1, min(most, int(0.1 * self.seconds / max(seconds, 1e-9)))):
            seconds, result = render()
            times.append(seconds)
        return times, result

    def renders(self, job, results, log):
        """(config, view key, view, record) for each render of `job` that fits: configurations in the job's
        order, views from the fewest pixels up. Every render gets a record in `results`; a skipped one's
        says why."""
        for config in job["configs"]:
            for view_key, view in ordered(job["views"]):
                record = {"config": config["key"], "view": view_key}
                results.append(record)
                reason = self.skip_reason(config["key"], view)
                if reason:
                    record["skipped"] = reason
                    log(f"{config['key']} {view_key}: skipped, {reason}")
                    continue
                yield config, view_key, view, record
