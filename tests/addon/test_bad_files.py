"""Damaged and unreadable volume files in a scene rendered by the command line (a fresh Blender per
render, so that a crash would fail one test): the error names the object, the file and the cause,
the other volume still renders (its X-ray matches exact), and the output is written whole, by
rename, with nothing half-written beside it.

(Missing files, text files, unknown grids and vector grids: test_errors.py, in the same Blender.)"""

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import bpy
import pytest

import blender_scenes as bs
from _io_helpers import unprivileged_prefix
from pcvr_addon.io import image_io

ROOT = Path(__file__).resolve().parents[2]


def damage(path, case):
    data = path.read_bytes()
    if case == "truncated":
        path.write_bytes(data[: len(data) // 2])
    elif case == "zero_length":
        path.write_bytes(b"")
    elif case == "byte_flipped":  # the middle of the grid's compressed values
        flipped = bytearray(data)
        flipped[len(data) // 2] ^= 0xFF
        flipped[len(data) // 2 + 7] ^= 0x55
        path.write_bytes(bytes(flipped))
    elif case == "directory":
        path.unlink()
        path.mkdir()
    elif case == "unreadable":
        path.chmod(0)


CAUSES = {
    "truncated": "truncated",
    "zero_length": "not a VDB file",
    "byte_flipped": "corrupt",
    "directory": "it is a directory",
    "unreadable": "permission denied",
    "missing_frame": "frame 2 of the sequence",
}


def scene_with_a_bad_volume(directory, case):
    """Saves directory/scene.blend: 'Good' at x = -0.5 and 'Bad' at x = 0.5, whose file is damaged
    as `case` says. Returns the exact X-ray of the good volume alone."""
    bs.setup(48, 48)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=3.0)
    good = bs.add_volume("Good", bs.write_vdb(directory / "good.vdb", bs.box()), location=(-0.5, 0.0, 0.0))
    if case == "missing_frame":
        for frame in (1, 3):
            bs.write_vdb(directory / f"bad_{frame:04d}.vdb", bs.box())
        bad = bs.add_volume("Bad", directory / "bad_0001.vdb", location=(0.5, 0.0, 0.0))
        bad.data.is_sequence = True
        bad.data.frame_start, bad.data.frame_duration = 1, 3
        bpy.context.scene.frame_current = 2
    else:
        path = Path(bs.write_vdb(directory / "bad.vdb", bs.box()))
        bs.add_volume("Bad", path, location=(0.5, 0.0, 0.0))
    reference = bs.exact(bs.world_grid(good))
    bpy.ops.wm.save_as_mainfile(filepath=str(directory / "scene.blend"), copy=True)
    if case != "missing_frame":
        damage(path, case)
    return reference


def render(directory, prefix=()):
    """The command line's render of directory/scene.blend, run after `prefix` (e.g. as another user)."""
    command = [*prefix, sys.executable, "-m", "pcvr_addon", "render", str(directory / "scene.blend"),
               "-o", str(directory / "out" / "scene.exr"), "--method", "regular"]
    return subprocess.run(command, cwd=ROOT, env=dict(os.environ, HOME=str(directory)), capture_output=True, text=True,
                          timeout=300)


@pytest.fixture
def shared_dir():
    """A directory any user may use (pytest's tmp_path is private to its owner)."""
    directory = Path(tempfile.mkdtemp(prefix="pcvr_bad_files_"))
    directory.chmod(0o777)
    (directory / "out").mkdir()
    (directory / "out").chmod(0o777)
    yield directory
    for path in directory.rglob("*"):
        if not path.is_symlink():
            path.chmod(0o777 if path.is_dir() else 0o666)
    shutil.rmtree(directory)


@pytest.mark.parametrize("case", list(CAUSES))
def test_bad_file_is_reported_and_the_rest_renders(shared_dir, case):
    prefix = []
    if case == "unreadable":  # as 'nobody' when root, who may read anything
        prefix, why_not = unprivileged_prefix()
        if prefix is None:
            pytest.skip(why_not)
    reference = scene_with_a_bad_volume(shared_dir, case)
    for path in shared_dir.iterdir():
        if path.is_file() and case != "unreadable":
            path.chmod(0o644)
    run = render(shared_dir, prefix)
    assert run.returncode == 1, run.stdout + run.stderr
    bad_file = "bad_0001.vdb" if case == "missing_frame" else "bad.vdb"
    for words in ("Volume object 'Bad'", bad_file, CAUSES[case]):
        assert words in run.stderr, run.stderr
    output = shared_dir / "out" / "scene.exr"
    bs.assert_matches(image_io.read_passes(str(output))[""][:, :, 4], reference)
    assert [p.name for p in output.parent.iterdir()] == ["scene.exr"], "a temporary file was left"
