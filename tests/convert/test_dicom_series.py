"""DICOM series into grids: geometry, Hounsfield units, series choice and refusals, all against the arrays
and positions that made the files (tests/scan_files.py)."""

import os

import numpy as np
import pytest

import scan_files as sf
from pcvr_addon import volume_import
from pcvr_addon.volume_import import ScanError

# An oblique series: rows run along (cos 30°, sin 30°, 0), columns down (0, cos 20°, -sin 20°) rotated
# accordingly; not along any axis, so a swapped or transposed axis shows.
ROW = np.array([np.cos(np.radians(30)), np.sin(np.radians(30)), 0.0])
COLUMN = np.cross([0.3, -0.2, 0.93], ROW)
COLUMN /= np.linalg.norm(COLUMN)
NORMAL = np.cross(ROW, COLUMN)
ORIGIN = np.array([-120.5, 33.25, 410.0])
PIXEL_SPACING = (0.7, 0.9)   # between rows, between columns
SLICE_SPACING = 1.25


def ct_series(folder, rng, shape=(6, 5, 7), **kwargs):
    stored = rng.integers(-1024, 3000, size=shape).astype(np.int16)
    options = dict(origin=ORIGIN, row_direction=ROW, column_direction=COLUMN, pixel_spacing=PIXEL_SPACING,
                   step=NORMAL * SLICE_SPACING, slope=1.0, intercept=-1024.0)
    options.update(kwargs)
    return stored, sf.dicom_series(str(folder), stored, **options)


def test_values_are_hounsfield_units_exactly(tmp_path, rng):
    stored, _ = ct_series(tmp_path, rng, slope=2.0, intercept=-1024.0)
    volume = volume_import.open_volume(str(tmp_path))
    grid = volume_import.to_grid(volume)
    expected = stored.astype(np.float64) * 2.0 - 1024.0
    assert volume.shape == stored.shape
    assert grid.background == expected.min()  # the lowest value is the inactive background
    np.testing.assert_array_equal(sf.dense_values(grid, stored.shape, grid.background), expected.astype(np.float32))
    assert (volume.modality, volume.units) == ("CT", "HU")


def test_each_voxel_lands_at_its_patient_position(tmp_path, rng):
    stored, _ = ct_series(tmp_path, rng)
    volume = volume_import.open_volume(str(tmp_path))
    for s, r, c in [(0, 0, 0), (5, 4, 6), (2, 3, 1)]:
        # DICOM: pixel (row r, column c) of slice s lies at its position + c * column spacing along the row
        # direction + r * row spacing along the column direction.
        patient = ORIGIN + s * SLICE_SPACING * NORMAL + c * PIXEL_SPACING[1] * ROW + r * PIXEL_SPACING[0] * COLUMN
        np.testing.assert_allclose(sf.world(volume.index_to_world, (s, r, c)), patient, atol=1e-9)
    np.testing.assert_allclose(volume.spacing, (SLICE_SPACING, *PIXEL_SPACING), rtol=1e-12)


def test_slices_are_ordered_by_position_not_by_name_or_number(tmp_path, rng):
    stored, files = ct_series(tmp_path, rng, shape=(9, 3, 4))
    volume = volume_import.open_volume(files[4])  # one file of the series names it
    grid = volume_import.to_grid(volume, background=-5000.0)
    np.testing.assert_array_equal(grid.to_dense(fill=-5000.0), stored.astype(np.float32) - 1024.0)


def test_slab_boundaries_do_not_change_the_grid(tmp_path, rng, monkeypatch):
    """One plane a slab (DICOM's) and the whole array at once build the same grid: the partial leaves a
    slab leaves are completed by the next."""
    import pcvr_native as pn

    stored, _ = ct_series(tmp_path, rng, shape=(19, 11, 13))
    volume = volume_import.open_volume(str(tmp_path))
    whole = pn.Grid.from_dense(stored.astype(np.float32) - 1024.0, volume.index_to_world,
                               background=float(stored.min()) - 1024.0)
    sliced = volume_import.to_grid(volume)
    assert sliced.active_voxel_count == whole.active_voxel_count
    np.testing.assert_array_equal(sliced.to_dense(fill=-1e6), whole.to_dense(fill=-1e6))


def test_gantry_tilt_keeps_the_exact_sheared_geometry(tmp_path, rng):
    tilt = np.radians(15.0)
    step = SLICE_SPACING * (np.cos(tilt) * NORMAL + np.sin(tilt) * COLUMN)
    stored, _ = ct_series(tmp_path, rng, step=step)
    volume = volume_import.open_volume(str(tmp_path))
    np.testing.assert_allclose(volume.index_to_world[:3, 0], step, atol=1e-9)
    patient = ORIGIN + 4 * step + 3 * PIXEL_SPACING[1] * ROW + 2 * PIXEL_SPACING[0] * COLUMN
    np.testing.assert_allclose(sf.world(volume.index_to_world, (4, 2, 3)), patient, atol=1e-9)
    assert float(volume.metadata()["pcvr_gantry_tilt_degrees"]) == pytest.approx(15.0, abs=1e-3)


def test_a_missing_slice_is_refused_naming_the_files(tmp_path, rng):
    _, files = ct_series(tmp_path, rng, shape=(6, 3, 3))
    os.remove(files[3])
    with pytest.raises(ScanError, match=r"1 slice\(s\) missing between positions") as error:
        volume_import.open_volume(str(tmp_path))
    assert os.path.basename(files[2]) in str(error.value) and os.path.basename(files[4]) in str(error.value)


def test_uneven_spacing_is_refused_with_the_numbers(tmp_path, rng):
    positions = [ORIGIN + d * NORMAL for d in (0.0, 1.0, 2.0, 3.6, 4.6)]
    ct_series(tmp_path, rng, shape=(5, 3, 3), positions=positions)
    with pytest.raises(ScanError, match=r"slice spacing varies from 1\.000 to 1\.600 mm"):
        volume_import.open_volume(str(tmp_path))


def test_two_slices_at_one_position_are_refused(tmp_path, rng):
    positions = [ORIGIN + d * NORMAL for d in (0.0, 1.0, 1.0, 2.0)]
    ct_series(tmp_path, rng, shape=(4, 3, 3), positions=positions)
    with pytest.raises(ScanError, match="two slices at the same position"):
        volume_import.open_volume(str(tmp_path))


def test_mixed_series_are_listed_and_picked_by_index_or_uid(tmp_path, rng):
    ct, _ = ct_series(tmp_path / "a", rng, shape=(3, 4, 5), series_number=2, series_uid="1.2.3.4.2")
    mr = rng.integers(0, 900, size=(4, 6, 2)).astype(np.int16)
    sf.dicom_series(str(tmp_path / "b"), mr, modality="MR", series_number=5, series_uid="1.2.3.4.5")
    with pytest.raises(ScanError, match="2 series; pick one with --series") as error:
        volume_import.open_volume(str(tmp_path))
    listing = str(error.value)
    assert "[0] series 2: CT 5 x 4, 3 slice(s), UID 1.2.3.4.2" in listing
    assert "[1] series 5: MR 2 x 6, 4 slice(s), UID 1.2.3.4.5" in listing
    assert volume_import.open_volume(str(tmp_path), series="1").shape == mr.shape
    assert volume_import.open_volume(str(tmp_path), series="1.2.3.4.2").shape == ct.shape
    with pytest.raises(ScanError, match="no series '7'"):
        volume_import.open_volume(str(tmp_path), series="7")


def test_a_folder_without_a_series_is_refused(tmp_path):
    (tmp_path / "notes.txt").write_text("not DICOM")
    with pytest.raises(ScanError, match="no DICOM image series found"):
        volume_import.open_volume(str(tmp_path))


def test_compressed_pixels_without_a_decoder_are_refused_before_reading(tmp_path, rng):
    from pydicom.pixels import get_decoder
    from pydicom.uid import JPEG2000Lossless

    if get_decoder(JPEG2000Lossless).is_available:
        pytest.skip("a JPEG 2000 decoder is installed here")
    ct_series(tmp_path, rng, shape=(3, 4, 4), transfer_syntax=JPEG2000Lossless)
    with pytest.raises(ScanError, match=r"compressed as JPEG 2000 .*no decoder for it is installed"):
        volume_import.open_volume(str(tmp_path))


def test_no_patient_field_reaches_the_vdb_or_the_messages(tmp_path, rng):
    import pcvr_native as pn

    ct_series(tmp_path / "scan", rng, series_number=3)
    sf.dicom_series(str(tmp_path / "scan" / "other"), np.zeros((2, 2, 2), np.int16), series_number=4)
    with pytest.raises(ScanError) as error:
        volume_import.open_volume(str(tmp_path / "scan"))
    output = tmp_path / "ct.vdb"
    volume = volume_import.convert(str(tmp_path / "scan"), str(output), series="0")
    data = output.read_bytes()
    metadata = pn.list_grids(str(output))[0]["metadata"]
    for marker in sf.PATIENT_MARKERS:
        assert marker.encode() not in data
        assert marker not in str(error.value) and marker not in volume.description()
    assert metadata["pcvr_modality"] == "CT" and metadata["pcvr_units"] == "HU"
    assert metadata["pcvr_world"] == "LPS millimetres" and metadata["pcvr_series_number"] == "3"
