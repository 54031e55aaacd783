"""python -m pcvr_addon convert, and render of a scan: the same image as rendering its converted .vdb."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pcvr_native as pn

import scan_files as sf
from pcvr_addon.io import image_io

ROOT = Path(__file__).resolve().parents[2]


def pcvr(tmp_path, *args):
    # The render's conversion cache in the test's folder, not the user's.
    env = dict(os.environ, XDG_CACHE_HOME=str(tmp_path / "cache"))
    return subprocess.run([sys.executable, "-m", "pcvr_addon", *map(str, args)], cwd=ROOT, capture_output=True,
                          text=True, timeout=300, env=env)


def test_convert_writes_the_vdb_and_says_what_it_holds(tmp_path, rng):
    values = rng.integers(0, 500, size=(6, 5, 4)).astype(np.int16)
    scan = sf.nifti(str(tmp_path / "head.nii.gz"), values, np.diag([0.5, 0.5, 2.0, 1.0]))
    run = pcvr(tmp_path, "convert", scan, "-o", tmp_path / "head.vdb")
    assert run.returncode == 0, run.stderr
    assert "wrote" in run.stdout and "NIfTI volume, 4 x 5 x 6 voxels of 2 x 0.5 x 0.5 mm" in run.stdout
    assert pn.list_grids(str(tmp_path / "head.vdb"))[0]["metadata"]["pcvr_source_format"] == "NIfTI"


def test_convert_lists_the_series_and_writes_nothing_until_one_is_picked(tmp_path, rng):
    for number in (2, 3):
        sf.dicom_series(str(tmp_path / "study" / f"s{number}"), rng.integers(0, 9, (2, 3, 3)).astype(np.int16),
                        series_number=number)
    run = pcvr(tmp_path, "convert", tmp_path / "study", "-o", tmp_path / "ct.vdb")
    assert run.returncode == 1 and "2 series; pick one with --series" in run.stderr
    assert "[1] series 3: CT 3 x 3, 2 slice(s)" in run.stderr
    assert not (tmp_path / "ct.vdb").exists()
    for marker in sf.PATIENT_MARKERS:
        assert marker not in run.stdout + run.stderr
    run = pcvr(tmp_path, "convert", tmp_path / "study", "-o", tmp_path / "ct.vdb", "--series", 1)
    assert run.returncode == 0, run.stderr and (tmp_path / "ct.vdb").exists()


def test_render_of_a_scan_equals_render_of_its_vdb(tmp_path, rng):
    values = rng.integers(0, 1000, size=(8, 7, 6)).astype(np.int16)
    scan = sf.nifti(str(tmp_path / "scan.nii"), values, np.diag([1.0, 1.5, 2.0, 1.0]))
    assert pcvr(tmp_path, "convert", scan, "-o", tmp_path / "scan.vdb").returncode == 0
    for source, image in ((scan, "direct.exr"), (tmp_path / "scan.vdb", "via_vdb.exr")):
        run = pcvr(tmp_path, "render", source, "-o", tmp_path / image, "--magnification", 2)
        assert run.returncode == 0, run.stderr
    direct = image_io.read_passes(str(tmp_path / "direct.exr"))[""]
    via_vdb = image_io.read_passes(str(tmp_path / "via_vdb.exr"))[""]
    assert direct.shape == via_vdb.shape and direct[..., 4].max() > 0
    np.testing.assert_array_equal(direct, via_vdb)
