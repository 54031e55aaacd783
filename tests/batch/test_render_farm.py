"""Render farms: `blender -b scene.blend -E PCVR -s 1 -e N -a` on a worker with only Blender and the extension
zip renders the frames a batch renders, pixel for pixel. (There is no Blender binary here, only the bpy
module: farm_render.py runs the same animation render through bpy.ops.render.render(animation=True) with the
extension installed from its zip, in a process that cannot import this repository.)"""

import os
import subprocess
import sys
from pathlib import Path

import bpy
import numpy as np
import pytest

import batch_helpers as bh
import batch_scenes
import pcvr_addon
from pcvr_addon.cli import command_scene
from pcvr_addon.io import image_io

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT / "tests" / "addon"))
from test_extension import archive  # noqa: E402  (the zip `make extension` builds)


def save_sequence_scene(sequence, blend, output):
    """A .blend showing the sequence as `render` frames it, writing 32-bit OpenEXR frames to `output`."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    pcvr_addon.register()
    try:
        scene = bpy.context.scene
        command_scene.vdb_scene(scene, str(sequence / "smoke_0001.vdb"))
        command_scene.apply_options(scene, bh.defaults())
        scene.render.filepath = str(output)
        scene.render.image_settings.file_format = 'OPEN_EXR'
        scene.render.image_settings.color_depth = '32'
        bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    finally:
        pcvr_addon.unregister()


def test_farm_animation_equals_the_batch(tmp_path):
    if not archive().is_file():
        pytest.skip(f"{archive().relative_to(ROOT)} is not built: run `make extension` (`make test` does)")
    sequence = tmp_path / "shared"
    batch_scenes.write_sequence(sequence, range(1, 4))
    blend = sequence / "smoke.blend"
    save_sequence_scene(sequence, blend, tmp_path / "farm" / "f_####")

    # Only Blender's own paths: not this repository, not the tests.
    environment = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "blender"), PYTHONPATH="")
    command = [sys.executable, str(HERE / "farm_render.py"), str(archive()), str(tmp_path), str(blend), "1", "3"]
    run = subprocess.run(command, env=environment, cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "rendered frames 1 to 3" in run.stdout

    status, printed = bh.render(blend, tmp_path / "batch" / "f_####.exr", range(1, 4))
    assert status == 0, printed
    for frame in range(1, 4):
        farm = image_io.read_passes(str(tmp_path / "farm" / f"f_{frame:04d}.exr"))
        batch = image_io.read_passes(str(tmp_path / "batch" / f"f_{frame:04d}.exr"))[""]
        # Blender writes the Combined pass as R, G, B, A.
        assert np.array_equal(farm[""][:, :, :4], batch[:, :, :4]), frame
    # The frames differ: the sequence plays.
    assert not np.array_equal(farm[""], image_io.read_passes(str(tmp_path / "farm" / "f_0001.exr"))[""])
