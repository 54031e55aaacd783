# SPDX-License-Identifier: GPL-3.0-or-later

"""What a batch renders: one Job per image, from the command line's patterns or from a job file.

| source                                   | jobs                                                    |
|------------------------------------------|---------------------------------------------------------|
| `DIR/f_####.vdb --frames 1-250 -o o_####.exr` | one per frame; `#`s stand for the zero-padded number |
| `vol.vdb --angles 0:360:10 -o v_###.png` | one per angle (an orbit about the volume); `#`s: the angle's index |
| both                                     | every frame from every angle; OUTPUT then needs two runs of `#`s (frame, angle) |
| `jobs.json` (see load_job_file)          | as listed, each with its own input, output, frame and angle |
"""

import json
import os
import re
from dataclasses import dataclass, field

_HASHES = re.compile(r"#+")


@dataclass(frozen=True)
class Job:
    input: str                  # a .vdb (a numbered one brings its sequence) or a .blend
    output: str                 # the image to write: .exr, .png or .tif
    frame: int | None = None    # the scene frame; for a numbered .vdb the number of its file
    angle: float | None = None  # degrees of orbit about the volume (None: the camera as it is)
    options: dict = field(default_factory=dict, compare=False)  # the render options (cli names) of this job
    scene: str | None = None    # a sequence's frame the scene is made from (framed on), None: `input`

    @property
    def scene_key(self):
        """Jobs with the same key share one Blender scene when planned: the same scene file and options."""
        return (self.scene or self.input, json.dumps(self.options, sort_keys=True))


def parse_frames(text):
    """'A-B' (inclusive) or 'A' as a range of frame numbers; ValueError otherwise."""
    match = re.fullmatch(r"\s*(-?\d+)\s*(?:-\s*(-?\d+)\s*)?", text)
    if not match:
        raise ValueError(f"--frames '{text}' is not A-B, e.g. 1-250")
    first = int(match.group(1))
    last = int(match.group(2)) if match.group(2) is not None else first
    if last < first:
        raise ValueError(f"--frames '{text}': the last frame comes before the first")
    return range(first, last + 1)


def parse_angles(text):
    """'START:STOP:STEP' in degrees, STOP excluded as in Python's range: [0, 10, ..., 350] for '0:360:10'."""
    try:
        start, stop, step = (float(value) for value in text.split(":"))
    except ValueError:
        raise ValueError(f"--angles '{text}' is not START:STOP:STEP in degrees, e.g. 0:360:10") from None
    if step == 0 or (stop - start) / step <= 0:
        raise ValueError(f"--angles '{text}': no angle from {start:g} towards {stop:g} in steps of {step:g}")
    count = int(-(-(stop - start) // step))  # ceil: STOP itself excluded
    return [start + index * step for index in range(count)]


def hash_runs(path):
    """How many runs of '#' the file name of `path` holds."""
    return len(_HASHES.findall(os.path.basename(path)))


def fill(path, *numbers):
    """`path` with its runs of '#' in the file name replaced, left to right, by `numbers`, each zero-padded to
    its run's length: fill('o/f_####.exr', 7) == 'o/f_0007.exr'."""
    directory, name = os.path.split(path)
    values = iter(numbers)
    name = _HASHES.sub(lambda run: f"{next(values):0{len(run.group())}d}", name)
    return os.path.join(directory, name)


def expand(input_path, output_path, frames=None, angles=None, options=None):
    """The jobs of one command line: each frame of `frames` (a range, or None for the input's own) from each of
    `angles` (degrees, or None for the camera as it is). ValueError when the paths' '#'s do not fit."""
    options = dict(options or {})
    frame_list = list(frames) if frames is not None else [None]
    angle_list = list(angles) if angles is not None else [None]
    if frames is not None and input_path.lower().endswith(".vdb") and hash_runs(input_path) != 1:
        raise ValueError(f"INPUT '{input_path}' needs one run of '#' for the frame number with --frames, "
                         "e.g. smoke_####.vdb")
    wanted = (frames is not None) + (angles is not None)
    if hash_runs(output_path) != wanted:
        raise ValueError(f"OUTPUT '{output_path}' needs {wanted} run{'s' if wanted != 1 else ''} of '#' "
                         "(the frame number, then the angle's index), e.g. out_####.exr")
    sequence = frames is not None and hash_runs(input_path) > 0
    # A sequence is one scene, made from (and framed on) its first frame: the camera stays put while it plays.
    scene = fill(input_path, frame_list[0]) if sequence else None
    jobs = []
    for frame in frame_list:
        source = fill(input_path, frame) if sequence else input_path
        for index, angle in enumerate(angle_list):
            numbers = [n for n in (frame, index if angle is not None else None) if n is not None]
            jobs.append(Job(source, fill(output_path, *numbers), frame, angle, options, scene))
    return jobs


def load_job_file(path):
    """The jobs of a JSON job file: {"options": {...}, "jobs": [{"input", "output", "frame"?, "angle"?,
    "options"?}, ...]}, relative paths from the file's folder, each job's options over the shared ones.
    ValueError naming the file and the job for anything else."""
    try:
        with open(path, encoding="utf-8") as file:
            document = json.load(file)
    except (OSError, json.JSONDecodeError) as ex:
        raise ValueError(f"job file '{path}': {ex}") from None
    if not isinstance(document, dict) or not isinstance(document.get("jobs"), list):
        raise ValueError(f"job file '{path}': expected an object with a list \"jobs\"")
    base = os.path.dirname(os.path.abspath(path))
    shared = document.get("options", {})
    jobs = []
    for number, entry in enumerate(document["jobs"]):
        if not isinstance(entry, dict) or not {"input", "output"} <= entry.keys():
            raise ValueError(f"job file '{path}', job {number}: needs \"input\" and \"output\"")
        unknown = entry.keys() - {"input", "output", "frame", "angle", "options"}
        if unknown:
            raise ValueError(f"job file '{path}', job {number}: unknown keys {sorted(unknown)}")
        jobs.append(Job(os.path.join(base, entry["input"]), os.path.join(base, entry["output"]),
                        entry.get("frame"), entry.get("angle"), {**shared, **entry.get("options", {})}))
    return jobs


def in_groups(items, size, key=lambda job: job.scene_key):
    """`items` (Jobs, or anything `key` maps to a Job's scene_key) cut into tasks of at most `size`, never
    mixing scenes, each scene's in order: a worker renders a task's images from the grids it read for the
    first (and keeps them for its next task of the same volume)."""
    by_scene = {}
    for item in items:
        by_scene.setdefault(key(item), []).append(item)
    return [scene_items[start:start + size] for scene_items in by_scene.values()
            for start in range(0, len(scene_items), size)]
