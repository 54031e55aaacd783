# SPDX-License-Identifier: GPL-3.0-or-later

"""The manifest of a batch: one JSON file beside its images with the settings every image was rendered with
and, per image, its status, time and the native statistics. Written atomically, also when the batch is
interrupted (the images not rendered are listed as "not rendered": `--skip-existing` renders them next)."""

import json
import os
import uuid

FORMAT = "pcvr-batch-manifest/1"


def manifest_path(output_pattern):
    """Where a batch writing `output_pattern` (e.g. out/frame_####.exr) puts its manifest: out/frame.manifest.json."""
    directory, name = os.path.split(output_pattern)
    stem = os.path.splitext(name)[0].replace("#", "").rstrip("_-. ") or "batch"
    return os.path.join(directory, stem + ".manifest.json")


def job_entry(planned_or_job, result=None, status=None):
    """One image's entry: what it shows, where it went and how it went."""
    job = getattr(planned_or_job, "job", planned_or_job)
    entry = {"input": job.input, "output": job.output, "frame": job.frame, "angle": job.angle}
    if job.options:
        entry["options"] = job.options
    if result is None:
        entry["status"] = status
        return entry
    entry.update(status=result.status, seconds=round(result.seconds, 4), worker=result.worker, stats=result.stats)
    if result.errors:
        entry["errors"] = result.errors
    return entry


def write(path, document):
    """`document` as JSON at `path`, through a temporary file renamed into place."""
    directory = os.path.dirname(os.path.abspath(path))
    os.makedirs(directory, exist_ok=True)
    temporary = os.path.join(directory, f".{os.path.basename(path)}.{uuid.uuid4().hex[:8]}")
    try:
        with open(temporary, "w", encoding="utf-8") as file:
            json.dump({"format": FORMAT, **document}, file, indent=1)
            file.write("\n")
        os.replace(temporary, path)
    except BaseException:
        if os.path.exists(temporary):
            os.remove(temporary)
        raise
