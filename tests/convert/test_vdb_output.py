"""The .vdb a scan becomes: what it renders, what it records, and nothing left behind when it fails."""

import os

import numpy as np
import pytest

import scan_files as sf
from pcvr_addon import volume_import
from pcvr_addon.volume_import import ScanError
from xray_helpers import frame_ortho

pn = pytest.importorskip("pcvr_native")


def test_render_of_a_converted_scan_equals_the_render_of_its_array(tmp_path, rng):
    """The same voxels, background and transform as Grid.from_dense of the array that made the file: the
    renders are equal to the last bit."""
    values = rng.integers(-1000, 1500, size=(9, 10, 11)).astype(np.int16)  # [x, y, z]
    affine = np.array([[0.9, 0.1, 0.0, -4.0], [-0.1, 0.9, 0.2, 3.0], [0.0, -0.2, 1.5, 7.0], [0, 0, 0, 1]])
    path = sf.nifti(str(tmp_path / "ct.nii.gz"), values, affine)
    output = tmp_path / "ct.vdb"
    volume = volume_import.convert(path, str(output))

    converted = pn.read_vdb(str(output))
    reference = pn.Grid.from_dense(np.transpose(values, (2, 1, 0)).astype(np.float32), volume.index_to_world,
                                   background=float(values.min()))
    np.testing.assert_allclose(converted.index_to_world, reference.index_to_world, rtol=0, atol=1e-12)
    cam = frame_ortho(reference, magnification=2.0, direction=(0.3, -0.2, -1.0)).camera()
    np.testing.assert_array_equal(pn.render_xray(converted, cam), pn.render_xray(reference, cam))
    assert converted.background == reference.background


def test_metadata_records_the_scan_without_a_patient(tmp_path, rng):
    stored = rng.integers(0, 100, size=(3, 4, 5)).astype(np.int16)
    sf.dicom_series(str(tmp_path / "mr"), stored, modality="MR", series_number=8)
    output = tmp_path / "mr.vdb"
    volume_import.convert(str(tmp_path / "mr"), str(output))
    (info,) = pn.list_grids(str(output))
    assert info["name"] == "density"
    meta = info["metadata"]
    assert meta["pcvr_modality"] == "MR" and "pcvr_units" not in meta
    assert meta["pcvr_description"] == "MR DICOM volume, 3 x 4 x 5 voxels of 1 x 1 x 1 mm"
    assert meta["pcvr_source_format"] == "DICOM"


def test_a_failed_conversion_leaves_no_file(tmp_path, rng):
    values = rng.integers(0, 100, size=(4, 4, 4)).astype(np.int16)
    truncated = sf.metaimage(str(tmp_path / "cut.mha"), values, (1, 1, 1), (0, 0, 0), np.eye(3))
    with open(truncated, "r+b") as f:
        f.truncate(f.seek(0, 2) - 10)
    before = sorted(os.listdir(tmp_path))
    with pytest.raises(ScanError, match="cut.mha: truncated"):
        volume_import.convert(truncated, str(tmp_path / "cut.vdb"))
    assert sorted(os.listdir(tmp_path)) == before
