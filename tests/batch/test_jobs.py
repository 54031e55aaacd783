"""Jobs from the command line's patterns and from job files, and the progress line (no rendering)."""

import json

import pytest

from pcvr_addon.batch import jobs, manifest
from pcvr_addon.batch.progress import ProgressBar, format_duration


def test_frames_and_angles():
    assert list(jobs.parse_frames("3-6")) == [3, 4, 5, 6]
    assert list(jobs.parse_frames("7")) == [7]
    assert jobs.parse_angles("0:360:90") == [0.0, 90.0, 180.0, 270.0]
    assert jobs.parse_angles("0:100:30") == [0.0, 30.0, 60.0, 90.0]
    assert jobs.parse_angles("90:0:-45") == [90.0, 45.0]
    for bad in ("6-3", "a-b", "1-"):
        with pytest.raises(ValueError, match="--frames"):
            jobs.parse_frames(bad)
    for bad in ("0:360", "0:360:0", "0:-10:5", "x:1:1"):
        with pytest.raises(ValueError, match="--angles"):
            jobs.parse_angles(bad)


def test_expand_fills_hashes_frame_then_angle():
    expanded = jobs.expand("in/smoke_####.vdb", "out/f_###_##.exr", range(9, 11), [0.0, 45.0])
    assert [(j.input, j.output, j.frame, j.angle) for j in expanded] == [
        ("in/smoke_0009.vdb", "out/f_009_00.exr", 9, 0.0), ("in/smoke_0009.vdb", "out/f_009_01.exr", 9, 45.0),
        ("in/smoke_0010.vdb", "out/f_010_00.exr", 10, 0.0), ("in/smoke_0010.vdb", "out/f_010_01.exr", 10, 45.0)]
    # A .blend plays its own frames: no '#' in INPUT.
    assert jobs.expand("scene.blend", "o_#.png", range(1, 3))[1].input == "scene.blend"


@pytest.mark.parametrize("input_path, output, frames, angles, message", [
    ("smoke.vdb", "o_####.exr", range(1, 3), None, "INPUT"),
    ("smoke_####.vdb", "o.exr", range(1, 3), None, "OUTPUT"),
    ("v_#.vdb", "o_##.exr", range(1, 3), [0.0], "2 runs"),
])
def test_expand_names_the_path_without_its_hashes(input_path, output, frames, angles, message):
    with pytest.raises(ValueError, match=message):
        jobs.expand(input_path, output, frames, angles)


def test_job_file(tmp_path):
    path = tmp_path / "jobs.json"
    path.write_text(json.dumps({"options": {"mode": "MIP"}, "jobs": [
        {"input": "a.vdb", "output": "a.exr"},
        {"input": "b.vdb", "output": "b.png", "angle": 30, "options": {"mode": "XRAY"}}]}))
    loaded = jobs.load_job_file(str(path))
    assert [(j.input, j.output, j.angle, j.options) for j in loaded] == [
        (str(tmp_path / "a.vdb"), str(tmp_path / "a.exr"), None, {"mode": "MIP"}),
        (str(tmp_path / "b.vdb"), str(tmp_path / "b.png"), 30, {"mode": "XRAY"})]
    path.write_text(json.dumps({"jobs": [{"input": "a.vdb", "output": "a.exr", "zoom": 2}]}))
    with pytest.raises(ValueError, match=r"jobs.json', job 0: unknown keys \['zoom'\]"):
        jobs.load_job_file(str(path))
    path.write_text("{")
    with pytest.raises(ValueError, match="jobs.json"):
        jobs.load_job_file(str(path))


def test_groups_keep_scenes_apart_and_in_order():
    expanded = jobs.expand("a.vdb", "a_#.exr", angles=[0.0, 1.0, 2.0]) + jobs.expand("b.vdb", "b_#.exr", angles=[0.0])
    groups = jobs.in_groups(expanded, 2)
    assert [[j.output for j in group] for group in groups] == [["a_0.exr", "a_1.exr"], ["a_2.exr"], ["b_0.exr"]]


def test_manifest_path():
    assert manifest.manifest_path("out/frame_####.exr") == "out/frame.manifest.json"
    assert manifest.manifest_path("####.png") == "batch.manifest.json"


class _Stream:
    def __init__(self):
        self.text = ""

    def write(self, text):
        self.text += text

    def flush(self):
        pass


def test_progress_line_shows_rate_and_time_left():
    now = [0.0]
    stream = _Stream()
    bar = ProgressBar(40, stream, clock=lambda: now[0])
    now[0] = 10.0
    bar.advance(10)
    assert bar.line().endswith("10/40 images | 1.00/s | 0:30 left")
    assert format_duration(3725) == "1:02:05"
    now[0] = 40.0
    bar.advance(30)
    assert stream.text.splitlines()[-1].endswith("40/40 images | 0:40")
