"""Batches in one process: the same pixels as `python -m pcvr_addon render` of each image, a manifest, and
--skip-existing after an interruption."""

import json
import os

import numpy as np
import pytest

import batch_helpers as bh
import batch_scenes
from pcvr_addon.cli import main as cli
from pcvr_addon.io import image_io
from pcvr_addon.batch import render_task


@pytest.fixture(scope="module")
def sequence(tmp_path_factory):
    directory = tmp_path_factory.mktemp("sequence")
    batch_scenes.write_sequence(directory, range(1, 5))
    return directory


@pytest.mark.parametrize("mode, extension", [("XRAY", ".exr"), ("SHADED", ".exr"), ("MIP", ".png")])
def test_a_frame_of_a_batch_is_the_render_of_its_file(tmp_path, sequence, mode, extension):
    status, printed = bh.render(sequence / "smoke_####.vdb", tmp_path / "batch" / f"f_####{extension}", range(2, 4),
                                options={"mode": mode, "preset": None if mode == "XRAY" else "CT Bone"})
    assert status == 0, printed
    single = tmp_path / f"single{extension}"
    argv = ["render", str(sequence / "smoke_0003.vdb"), "-o", str(single), "--mode", mode]
    assert cli.main(argv + ([] if mode == "XRAY" else ["--preset", "CT Bone"])) == 0
    batch = image_io.read_passes(str(tmp_path / "batch" / f"f_0003{extension}"))[""]
    assert batch.shape[2] == {"XRAY": 5, "SHADED": 6, "MIP": 4}[mode]  # RGBA (Z) (XRay), as render writes
    assert np.array_equal(batch, image_io.read_passes(str(single))[""])


def test_angle_zero_is_the_camera_as_it_is_and_others_differ(tmp_path, sequence):
    status, printed = bh.render(sequence / "smoke_0001.vdb", tmp_path / "v_#.exr", angles=[0.0, 90.0, 180.0])
    assert status == 0, printed
    assert cli.main(["render", str(sequence / "smoke_0001.vdb"), "-o", str(tmp_path / "plain.exr")]) == 0
    views = bh.images(tmp_path)
    assert np.array_equal(views["v_0.exr"], views["plain.exr"])
    top, side, below = (views[f"v_{index}.exr"][:, :, 4] for index in range(3))
    # Seen from the side the blob, off centre along x, is elsewhere; every orthographic view at the same pixel
    # size holds the same total integral (measured: equal to 1e-6).
    assert not np.allclose(side, top, atol=0.05)
    for view in (side, below):
        assert view.sum() == pytest.approx(top.sum(), rel=1e-5)
    # From below, the mirror image of the view from above (the same line integrals), up to where the
    # footprints fall on the pixels: measured 0.0066 of a peak of 0.87 with the paper's passband, 0.0098
    # with the compensated one (the default: its sharper pass band moves with the subgrid's phase too).
    np.testing.assert_allclose(below[:, ::-1], top, atol=0.015 * top.max())


def test_manifest_lists_settings_and_stats(tmp_path, sequence):
    status, _ = bh.render(sequence / "smoke_####.vdb", tmp_path / "f_####.exr", range(1, 3), options={"gain": 2.0})
    assert status == 0
    with open(tmp_path / "f.manifest.json") as file:
        document = json.load(file)
    assert document["counts"] == {"rendered": 2}
    assert document["stream_above_mib"] > 0
    first = document["jobs"][0]
    assert (first["frame"], first["options"], first["status"]) == (1, {"gain": 2.0}, "rendered")
    assert first["stats"]["voxels"] == batch_scenes.SIZE ** 3
    assert image_io.description_of(str(tmp_path / "f_0001.exr")) == render_task.run_description(
        document["run_id"], 0)


def test_skip_existing_after_an_interruption(tmp_path, sequence, monkeypatch):
    output = tmp_path / "f_####.png"
    status, _ = bh.render(sequence / "smoke_####.vdb", tmp_path / "reference" / "f_####.png", range(1, 5))
    assert status == 0

    # Interrupted (Ctrl+C) while rendering the third image.
    render_job = render_task.render_job
    calls = []

    def interrupted(planned, run_id, *prepare):
        calls.append(planned.job.output)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return render_job(planned, run_id, *prepare)

    monkeypatch.setattr(render_task, "render_job", interrupted)
    status, printed = bh.render(sequence / "smoke_####.vdb", output, range(1, 5))
    assert status == 130 and "--skip-existing" in printed
    monkeypatch.undo()
    assert sorted(os.listdir(tmp_path)) == ["f.manifest.json", "f_0001.png", "f_0002.png", "reference"]
    with open(tmp_path / "f.manifest.json") as file:
        assert json.load(file)["counts"] == {"not rendered": 2, "rendered": 2}
    first_written = os.stat(tmp_path / "f_0001.png").st_mtime_ns

    status, printed = bh.render(sequence / "smoke_####.vdb", output, range(1, 5), skip_existing=True)
    assert status == 0, printed
    with open(tmp_path / "f.manifest.json") as file:
        assert json.load(file)["counts"] == {"rendered": 2, "skipped": 2}
    assert os.stat(tmp_path / "f_0001.png").st_mtime_ns == first_written
    reference = bh.images(tmp_path / "reference")
    bh.assert_same_images(bh.images(tmp_path), reference)


def test_bad_input_names_the_file(tmp_path):
    status, printed = bh.render(tmp_path / "missing_####.vdb", tmp_path / "f_####.exr", range(1, 3))
    assert status == 1 and "missing_0001.vdb' does not exist" in printed
    assert not any(name.endswith(".exr") for name in os.listdir(tmp_path))


def test_a_missing_frame_fails_alone(tmp_path):
    batch_scenes.write_sequence(tmp_path / "gap", [1, 3])
    status, printed = bh.render(tmp_path / "gap" / "smoke_####.vdb", tmp_path / "f_####.exr", range(1, 4))
    assert status == 1 and "smoke_0002.vdb" in printed
    with open(tmp_path / "f.manifest.json") as file:
        assert json.load(file)["counts"] == {"failed": 1, "rendered": 2}
    assert not (tmp_path / "f_0002.exr").exists()  # so that --skip-existing renders it once it is there


def test_job_file_from_the_command_line(tmp_path, sequence):
    jobs_file = tmp_path / "jobs.json"
    jobs_file.write_text(json.dumps({"options": {"magnification": 2.0}, "jobs": [
        {"input": str(sequence / "smoke_0001.vdb"), "output": "a.png"},
        {"input": str(sequence / "smoke_0002.vdb"), "output": "b.exr", "angle": 90, "options": {"mode": "MIP"}}]}))
    assert cli.main(["render", str(jobs_file), "-o", str(tmp_path / "results.json")]) == 0
    with open(tmp_path / "results.json") as file:
        document = json.load(file)
    assert document["counts"] == {"rendered": 2}
    assert image_io.read_passes(str(tmp_path / "a.png"))[""].shape == (56, 56, 4)  # 24 voxels + 4 of room, x2
    assert image_io.read_passes(str(tmp_path / "b.exr"))[""].shape[2] == 5  # RGBA and XRay, as render writes


@pytest.mark.parametrize("argv, message", [
    (["--frames", "1-3"], "INPUT"),
    (["--workers", "0"], "at least 1"),
    (["--workers", "2", "--scheduler", "tcp://x:1"], "one of them"),
    (["--angles", "0:90:45", "--preset", "No Such Preset"], "No Such Preset"),
    (["--angles", "0:90:45", "--clip-plane", "0", "0", "0", "1"], "--clip-plane needs a normal"),
])
def test_command_line_mistakes(tmp_path, sequence, capsys, argv, message):
    with pytest.raises(SystemExit):
        cli.main(["render", str(sequence / "smoke_0001.vdb"), "-o", str(tmp_path / "f_####.exr"), *argv])
    assert message in capsys.readouterr().err


@pytest.mark.parametrize("extension", [".png", ".tif"])
def test_a_task_run_again_keeps_what_its_run_wrote(tmp_path, sequence, extension):
    """What a task rerun by Dask (its worker lost) finds: the images its run wrote, whole, are kept, not written
    again; another run's images are rendered over."""
    output = tmp_path / f"f_####{extension}"
    assert bh.render(sequence / "smoke_####.vdb", output, range(1, 3), run_id="first")[0] == 0
    written = [os.stat(tmp_path / f"f_000{frame}{extension}").st_mtime_ns for frame in (1, 2)]
    assert bh.render(sequence / "smoke_####.vdb", output, range(1, 3), run_id="first")[0] == 0
    with open(tmp_path / "f.manifest.json") as file:
        assert json.load(file)["counts"] == {"kept": 2}
    assert [os.stat(tmp_path / f"f_000{frame}{extension}").st_mtime_ns for frame in (1, 2)] == written
    assert bh.render(sequence / "smoke_####.vdb", output, range(1, 3), run_id="second")[0] == 0
    with open(tmp_path / "f.manifest.json") as file:
        assert json.load(file)["counts"] == {"rendered": 2}


def test_job_file_clips_as_the_command_line_does(tmp_path, sequence):
    # The files' voxels of 0.1 span 0 to 2.4: the box keeps x < 1.2, the plane z > 0.8.
    clip = {"clip_box": [0.6, 1.2, 1.2, 0.6, 2.0, 2.0], "clip_plane": [[0.0, 0.0, 1.0, -0.8]]}
    jobs_file = tmp_path / "jobs.json"
    jobs_file.write_text(json.dumps({"options": {"magnification": 1.0, **clip}, "jobs": [
        {"input": str(sequence / "smoke_0001.vdb"), "output": "batch.exr"}]}))
    assert cli.main(["render", str(jobs_file), "-o", str(tmp_path / "results.json")]) == 0
    single = ["render", str(sequence / "smoke_0001.vdb"), "--magnification", "1"]
    clip_argv = ["--clip-box", *map(str, clip["clip_box"]), "--clip-plane", *map(str, clip["clip_plane"][0])]
    assert cli.main(single + ["-o", str(tmp_path / "single.exr")] + clip_argv) == 0
    assert cli.main(single + ["-o", str(tmp_path / "whole.exr")]) == 0
    batch, cut, whole = (image_io.read_passes(str(tmp_path / f"{name}.exr"))[""] for name in ("batch", "single", "whole"))
    np.testing.assert_array_equal(batch, cut)
    assert cut[..., 4].sum() < 0.8 * whole[..., 4].sum()
