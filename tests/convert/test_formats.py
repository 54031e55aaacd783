"""NIfTI, NRRD, MetaImage and TIFF stacks into grids: values against the arrays that made the files, voxel
positions against each format's own definition of its geometry, brought to LPS millimetres."""

import numpy as np
import pytest

import scan_files as sf
from pcvr_addon import volume_import
from pcvr_addon.volume_import import ScanError

RAS_TO_LPS = np.diag([-1.0, -1.0, 1.0, 1.0])


def oblique_axes():
    """Three axis steps (one per row) of different lengths, none along a world axis."""
    c, s = np.cos(0.4), np.sin(0.4)
    rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.array(
        [[1.0, 0.0, 0.0], [0.0, np.cos(0.3), -np.sin(0.3)], [0.0, np.sin(0.3), np.cos(0.3)]])
    return rotation.T * np.array([[0.8], [1.1], [2.5]])


ORIGIN = np.array([-91.5, 12.0, 37.25])
CORNERS = [(0, 0, 0), (4, 0, 0), (0, 5, 0), (0, 0, 6), (4, 5, 6), (1, 3, 2)]  # file index [x, y, z]


def file_values(rng, dtype=np.int16, shape=(5, 6, 7)):
    return rng.integers(0, 2000, size=shape).astype(dtype)


def check_volume(volume, values, world_of_file_index, atol=1e-9):
    """Grid [i, j, k] holds file [k, j, i] exactly, each at the world position the file defines."""
    grid = volume_import.to_grid(volume)
    expected = np.transpose(values, (2, 1, 0)).astype(np.float32)
    assert volume.shape == expected.shape
    np.testing.assert_array_equal(sf.dense_values(grid, expected.shape, grid.background), expected)
    for x, y, z in CORNERS:
        np.testing.assert_allclose(sf.world(volume.index_to_world, (z, y, x)), world_of_file_index((x, y, z)),
                                   atol=atol)


@pytest.mark.parametrize("name", ["oblique.nii", "oblique.nii.gz"])
def test_nifti_with_an_oblique_affine(tmp_path, rng, name):
    import nibabel

    values = file_values(rng)
    affine = np.eye(4)
    affine[:3, :3], affine[:3, 3] = oblique_axes().T, ORIGIN
    path = sf.nifti(str(tmp_path / name), values, affine)
    stored = nibabel.load(path).affine  # the file holds the affine in float32
    np.testing.assert_allclose(stored, affine, atol=1e-5)
    check_volume(volume_import.open_volume(path), values, lambda index: sf.world(RAS_TO_LPS @ stored, index))


def test_nifti_scaling_gives_physical_values(tmp_path, rng):
    values = file_values(rng)
    path = sf.nifti(str(tmp_path / "scaled.nii"), values, np.eye(4), slope=0.5, intercept=-100.0)
    grid = volume_import.to_grid(volume_import.open_volume(path))
    expected = np.transpose(values * 0.5 - 100.0, (2, 1, 0)).astype(np.float32)
    np.testing.assert_array_equal(sf.dense_values(grid, expected.shape, grid.background), expected)


def test_4d_nifti_needs_a_frame_and_converts_the_one_picked(tmp_path, rng):
    values = file_values(rng, shape=(3, 4, 5, 3))
    path = sf.nifti(str(tmp_path / "series.nii.gz"), values, np.diag([2.0, 2.0, 3.0, 1.0]))
    with pytest.raises(ScanError, match=r"series\.nii\.gz: a 4-D image of 3 volumes; pick one with --frame 0\.\.2"):
        volume_import.open_volume(path)
    with pytest.raises(ScanError, match="--frame 3 is outside"):
        volume_import.open_volume(path, frame=3)
    volume = volume_import.open_volume(path, frame=1)
    grid = volume_import.to_grid(volume)
    expected = np.transpose(values[..., 1], (2, 1, 0)).astype(np.float32)
    np.testing.assert_array_equal(sf.dense_values(grid, expected.shape, grid.background), expected)
    assert volume.metadata()["pcvr_frame"] == "1 of 3"


@pytest.mark.parametrize("encoding,detached", [("raw", False), ("gzip", False), ("gzip", True)])
def test_nrrd_in_ras_space(tmp_path, rng, encoding, detached):
    values = file_values(rng)
    directions = oblique_axes()
    path = sf.nrrd_file(str(tmp_path / ("volume.nhdr" if detached else "volume.nrrd")), values, directions,
                        ORIGIN, encoding=encoding, detached=detached)
    # NRRD: voxel [x, y, z] at origin + x * d0 + y * d1 + z * d2, in right-anterior-superior space.
    ras = lambda index: ORIGIN + np.asarray(index, float) @ directions
    check_volume(volume_import.open_volume(path), values, lambda index: (RAS_TO_LPS[:3, :3] @ ras(index)))


@pytest.mark.parametrize("compressed,detached", [(False, False), (True, False), (False, True)])
def test_metaimage_with_a_direction_matrix(tmp_path, rng, compressed, detached):
    values = file_values(rng)
    axes = oblique_axes()
    spacing = np.linalg.norm(axes, axis=1)
    directions = axes / spacing[:, None]   # row a: axis a's direction, as TransformMatrix lists them
    path = sf.metaimage(str(tmp_path / ("volume.mhd" if detached else "volume.mha")), values, spacing, ORIGIN,
                        directions, compressed=compressed, detached=detached)
    # ITK: voxel [x, y, z] at Offset + D @ (spacing * index), D's columns the axes' directions, LPS already.
    check_volume(volume_import.open_volume(path), values,
                 lambda index: ORIGIN + directions.T @ (spacing * np.asarray(index, float)), atol=1e-9)


def test_tiff_stack_with_imagej_spacing(tmp_path, rng):
    planes = rng.integers(0, 60000, size=(4, 5, 6)).astype(np.uint16)   # [plane, row, column]
    path = sf.tiff_stack(str(tmp_path / "stack.tif"), planes, spacing_um=(0.5, 0.25, 2.0))
    volume = volume_import.open_volume(path)
    grid = volume_import.to_grid(volume)
    np.testing.assert_array_equal(sf.dense_values(grid, planes.shape, grid.background), planes.astype(np.float32))
    # x along a row, y down the columns, z through the planes; micrometres to millimetres.
    np.testing.assert_allclose(sf.world(volume.index_to_world, (3, 4, 5)), [5 * 0.5e-3, 4 * 0.25e-3, 3 * 2e-3],
                               rtol=1e-6)


def test_ome_tiff_physical_size(tmp_path, rng):
    planes = rng.integers(0, 255, size=(3, 4, 5)).astype(np.uint8)
    path = sf.tiff_stack(str(tmp_path / "stack.ome.tif"), planes, spacing_um=(0.2, 0.3, 1.5), ome=True)
    volume = volume_import.open_volume(path)
    np.testing.assert_allclose(volume.spacing, (1.5e-3, 0.3e-3, 0.2e-3), rtol=1e-9)
    assert volume.metadata()["pcvr_spacing"] == "OME PhysicalSize"


def test_bad_files_are_refused_naming_the_file_and_cause(tmp_path, rng):
    not_nifti = tmp_path / "broken.nii"
    not_nifti.write_bytes(b"\0" * 10)
    with pytest.raises(ScanError, match="broken.nii: not a readable NIfTI file"):
        volume_import.open_volume(str(not_nifti))

    values = file_values(rng)
    truncated = sf.metaimage(str(tmp_path / "truncated.mha"), values, (1, 1, 1), (0, 0, 0), np.eye(3))
    with open(truncated, "r+b") as f:
        f.truncate(f.seek(0, 2) - 100)
    volume = volume_import.open_volume(truncated)
    with pytest.raises(ScanError, match=r"truncated\.mha: truncated: the header promises 420 bytes"):
        volume_import.to_grid(volume)

    with pytest.raises(ScanError, match="missing.nrrd: no such file"):
        volume_import.open_volume(str(tmp_path / "missing.nrrd"))
    with pytest.raises(ScanError, match="--series picks a DICOM series"):
        volume_import.open_volume(truncated, series="1")


def test_nan_becomes_the_background_and_infinity_is_refused(tmp_path, rng):
    values = rng.random((4, 5, 6)).astype(np.float32) + 1.0
    values[1, 2, 3] = values[0, 0, 0] = np.nan
    volume = volume_import.open_volume(sf.nifti(str(tmp_path / "masked.nii"), values, np.eye(4)))
    grid = volume_import.to_grid(volume)
    expected = np.transpose(values, (2, 1, 0))
    assert grid.background == np.nanmin(values)
    assert grid.active_voxel_count == values.size - 2 - int((values == np.nanmin(values)).sum())
    np.testing.assert_array_equal(sf.dense_values(grid, expected.shape, grid.background),
                                  np.where(np.isnan(expected), grid.background, expected))
    assert volume.metadata()["pcvr_nan_voxels_as_background"] == "2"

    values[1, 2, 3] = np.inf
    volume = volume_import.open_volume(sf.nifti(str(tmp_path / "infinite.nii"), values, np.eye(4)))
    with pytest.raises(ScanError, match=r"infinite.nii: Grid.from_slabs 'density': values contain infinity "
                                        r"at \[3, 2, 1\]"):
        volume_import.to_grid(volume)


def test_tiff_time_series_needs_a_frame(tmp_path, rng):
    stacks = rng.integers(0, 1000, size=(3, 4, 5, 6)).astype(np.uint16)   # [time, plane, row, column]
    path = str(tmp_path / "timelapse.tif")
    import tifffile
    tifffile.imwrite(path, stacks, imagej=True, metadata={"axes": "TZYX"})
    with pytest.raises(ScanError, match="a time series of 3 stacks; pick one with --frame 0..2"):
        volume_import.open_volume(path)
    volume = volume_import.open_volume(path, frame=2)
    grid = volume_import.to_grid(volume)
    np.testing.assert_array_equal(sf.dense_values(grid, stacks.shape[1:], grid.background),
                                  stacks[2].astype(np.float32))


def test_folder_of_tiff_planes_in_natural_order(tmp_path, rng):
    import tifffile

    planes = rng.integers(0, 4000, size=(11, 4, 5)).astype(np.uint16)
    for n, plane in enumerate(planes):   # slice_2 must come before slice_10
        tifffile.imwrite(str(tmp_path / f"slice_{n}.tif"), plane, resolution=(10.0, 10.0), resolutionunit=3)
    volume = volume_import.open_volume(str(tmp_path))
    grid = volume_import.to_grid(volume)
    np.testing.assert_array_equal(sf.dense_values(grid, planes.shape, grid.background), planes.astype(np.float32))
    # 10 pixels per centimetre: 1 mm, z taken as x's.
    np.testing.assert_allclose(volume.spacing, (1.0, 1.0, 1.0), rtol=1e-9)

    tifffile.imwrite(str(tmp_path / "slice_11.tif"), planes[0, :3])
    with pytest.raises(ScanError, match=r"slice_11.tif: a plane of \(3, 5\)"):
        volume_import.to_grid(volume_import.open_volume(str(tmp_path)))
