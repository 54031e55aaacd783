"""Scan files as other projects write them (issue 41, items 6-10): their own published test data, located
through the installed packages (nibabel's tests/data and nicom/tests/data, pydicom's data/test_files;
nibabel and pydicom are MIT-licensed), or files made here with the projects' own writers (pydicom,
nibabel, tifffile). Each is converted or refused as its format says, with a one-line cause and no library
warning on the way (`convert` on the command line: exit 1, one line on stderr)."""

import gzip
import os
import shutil
import subprocess
import sys
import warnings
from importlib import resources

import numpy as np
import pytest

import scan_files as sf
from pcvr_addon import volume_import
from pcvr_addon.volume_import import ScanError

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def package_file(package, path):
    """A file that `package` ships (its test data), or a skip naming the package's version."""
    found = resources.files(package).joinpath(path)
    if not found.is_file():
        from importlib.metadata import version
        pytest.skip(f"{package} {version(package)} does not ship {path}")
    return str(found)


def copied(package, path, folder, name=None):
    """The shipped file copied into `folder` (alone there: pydicom's test files share series UIDs)."""
    target = os.path.join(str(folder), name or os.path.basename(path))
    shutil.copyfile(package_file(package, path), target)
    return target


def refusal(path, **options):
    """The ScanError's message, with no warning let through."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ScanError) as error:
            volume = volume_import.open_volume(path, **options)
            for _slab in volume.read_slabs():
                pass
    return str(error.value)


def command_line(path, tmp_path):
    """`convert PATH`: (exit code, stdout, stderr)."""
    done = subprocess.run([sys.executable, "-m", "pcvr_addon", "convert", path, "-o", str(tmp_path / "out.vdb")],
                          capture_output=True, text=True, cwd=ROOT, timeout=120)
    return done.returncode, done.stdout, done.stderr


def values_of(volume):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return np.concatenate(list(volume.read_slabs()))


# 6. Files of formats not read, beside a DICOM series: refused with their format's name, never the series.
NOT_READ = [
    ("tests/data/test.mgz", "FreeSurfer MGH"),
    ("tests/data/tiny.mnc", "MINC"),
    ("tests/data/minc2_4d.mnc", "MINC"),
    ("tests/data/T1.PAR", "Philips PAR/REC"),
    ("tests/data/example4d+orig.HEAD", "AFNI BRIK/HEAD"),
    ("tests/data/scaled+tlrc.BRIK", "AFNI BRIK/HEAD"),
    ("tests/data/analyze.hdr", "an Analyze 7.5 header"),
    ("tests/data/nifti1.hdr", "the header of a NIfTI-1 pair"),
    ("tests/data/nifti2.hdr", "the header of a NIfTI-2 pair"),
    ("tests/data/tinypet.v", "ECAT 7"),
]


@pytest.mark.parametrize("shipped, name", NOT_READ, ids=[os.path.basename(p) for p, _n in NOT_READ])
def test_a_file_of_another_format_is_refused_not_the_folders_series(tmp_path, rng, shipped, name):
    sf.dicom_series(str(tmp_path), rng.integers(0, 100, size=(3, 4, 4)).astype(np.int16))
    path = copied("nibabel", shipped, tmp_path)
    message = refusal(path)
    assert message.startswith(f"{path}: {name}") and "not a format this converter reads" in message
    assert "it reads DICOM" in message and "NIfTI (.nii, .nii.gz)" in message and "TIFF" in message


def test_files_are_told_by_content_where_the_suffix_says_nothing(tmp_path, rng):
    files = sf.dicom_series(str(tmp_path / "series"), rng.integers(0, 100, size=(3, 4, 4)).astype(np.int16))
    for file in files:
        os.rename(file, file[:-len(".dcm")])   # scanners often write no suffix
    assert volume_import.open_volume(files[0][:-len(".dcm")]).shape == (3, 4, 4)

    mgz_without_suffix = copied("nibabel", "tests/data/test.mgz", tmp_path / "series", "IM9999")
    assert "gzip-compressed data of an unknown format" in refusal(mgz_without_suffix)
    not_dicom = copied("nibabel", "tests/data/test.mgz", tmp_path / "series", "IM9999.dcm")
    assert refusal(not_dicom) == f"{not_dicom}: not a DICOM file (no 'DICM' marker after the 128-byte preamble)"
    notes = tmp_path / "series" / "notes.xyz"
    notes.write_text("written by hand")
    assert refusal(str(notes)).startswith(f"{notes}: a file of unknown format ('.xyz', and its content is not")
    nifti = sf.nifti(str(tmp_path / "brain.nii"), np.zeros((2, 3, 4), np.int16), np.eye(4))
    os.rename(nifti, tmp_path / "brain")
    assert "a NIfTI file without the .nii suffix (rename it to .nii)" in refusal(str(tmp_path / "brain"))


def test_a_dicom_object_that_is_no_slice_says_what_it_is(tmp_path, rng):
    sf.dicom_series(str(tmp_path), rng.integers(0, 100, size=(3, 4, 4)).astype(np.int16))
    plan = copied("pydicom", "data/test_files/rtplan.dcm", tmp_path)
    assert refusal(plan) == (f"{plan}: a DICOM RT Plan Storage, which holds no image; DICOM converts as series "
                             "of single-frame slices or Siemens mosaics")
    ultrasound = copied("pydicom", "data/test_files/examples_rgb_color.dcm", tmp_path)
    assert "a DICOM Ultrasound Image Storage without an image position and orientation" in refusal(ultrasound)


def enhanced_multiframe(path, frames=3):
    """An Enhanced MR image as pydicom writes it: geometry per frame, none at the top level."""
    import pydicom
    from pydicom.dataset import Dataset, FileMetaDataset
    from pydicom.sequence import Sequence
    from pydicom.uid import EnhancedMRImageStorage, ExplicitVRLittleEndian, generate_uid

    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID, meta.MediaStorageSOPInstanceUID = EnhancedMRImageStorage, generate_uid()
    meta.TransferSyntaxUID = ExplicitVRLittleEndian
    ds = Dataset()
    ds.file_meta = meta
    ds.SOPClassUID, ds.SOPInstanceUID = meta.MediaStorageSOPClassUID, meta.MediaStorageSOPInstanceUID
    ds.SeriesInstanceUID, ds.Modality, ds.NumberOfFrames = generate_uid(), "MR", frames
    ds.Rows = ds.Columns = 4
    ds.SamplesPerPixel, ds.PhotometricInterpretation = 1, "MONOCHROME2"
    ds.BitsAllocated, ds.BitsStored, ds.HighBit, ds.PixelRepresentation = 16, 16, 15, 0
    groups = []
    for n in range(frames):
        position, group = Dataset(), Dataset()
        position.ImagePositionPatient = [0.0, 0.0, float(n)]
        group.PlanePositionSequence = Sequence([position])
        groups.append(group)
    ds.PerFrameFunctionalGroupsSequence = Sequence(groups)
    ds.PixelData = np.zeros((frames, 4, 4), "<u2").tobytes()
    pydicom.dcmwrite(path, ds, enforce_file_format=True)
    return path


def test_enhanced_multiframe_dicom_is_named_not_unfound(tmp_path):
    path = enhanced_multiframe(str(tmp_path / "enhanced.dcm"))
    assert refusal(path) == (f"{path}: a DICOM Enhanced MR Image Storage (a multi-frame image whose geometry is "
                             "given per frame, 3 frame(s)), which does not convert; DICOM converts as series of "
                             "single-frame slices or Siemens mosaics")
    message = refusal(str(tmp_path))
    assert message.startswith(f"{tmp_path}: no DICOM image series found")
    assert "1 file(s): a DICOM Enhanced MR Image Storage (a multi-frame image" in message
    assert "(e.g. enhanced.dcm)" in message and "Supported: DICOM" in message


# 7. Siemens mosaics: unpacked with nibabel's MosaicWrapper's geometry, or refused when they do not tile.
def test_siemens_mosaic_unpacks_as_nibabels_mosaic_wrapper_reads_it(tmp_path):
    import pydicom

    path = str(tmp_path / "siemens_dwi_1000.dcm")
    with gzip.open(package_file("nibabel", "nicom/tests/data/siemens_dwi_1000.dcm.gz")) as packed:
        with open(path, "wb") as out:
            shutil.copyfileobj(packed, out)
    volume = volume_import.open_volume(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # nibabel: "The DICOM readers are highly experimental"
        from nibabel.nicom import dicomwrappers
        wrapper = dicomwrappers.wrapper_from_data(pydicom.dcmread(path))
        expected = wrapper.get_data()     # [row, column, slice], scaled
    assert isinstance(wrapper, dicomwrappers.MosaicWrapper) and wrapper.image_shape == (128, 128, 48)
    assert volume.shape == (48, 128, 128)
    # Grid index [slice, row, column]: nibabel's affine with its columns in that order; to 1e-3 mm, as the
    # converter makes the orientation's cosines (0.999986, -0.005236 in this file) unit vectors.
    np.testing.assert_allclose(volume.index_to_world, wrapper.affine[:, [2, 0, 1, 3]], atol=1e-3)
    np.testing.assert_array_equal(values_of(volume), np.transpose(expected, (2, 0, 1)).astype(np.float32))
    assert volume.modality == "MR" and volume.notes["mosaic"] == "48 images in 7 x 7 tiles"


def test_a_mosaic_whose_frame_does_not_tile_is_refused(tmp_path):
    # nibabel's 0.dcm: NumberOfImagesInMosaic 48 (7 x 7 tiles) in a 256 x 256 frame; nibabel's own
    # MosaicWrapper.get_data() fails on it too.
    path = copied("nibabel", "nicom/tests/data/0.dcm", tmp_path)
    assert refusal(path) == (f"{path}: a Siemens mosaic of 48 images, which its 256 x 256 frame cannot hold as "
                             "7 x 7 equal tiles (256 and 256 are not multiples of 7: its pixel data were cropped "
                             "or resized?)")
    # Its folder holds it with 1.dcm in one series: two mosaics, each a whole volume.
    copied("nibabel", "nicom/tests/data/1.dcm", tmp_path)
    assert "holds 2 Siemens mosaics, each a whole volume" in refusal(str(tmp_path))


# 8. Malformed headers: a ScanError naming the field, no traceback.
def test_a_malformed_number_of_frames_is_a_clear_error(tmp_path):
    path = copied("pydicom", "data/test_files/badVR.dcm", tmp_path)
    assert refusal(path) == f"{path}: a malformed DICOM header: NumberOfFrames '1A' is not a whole number"


# 10. Values in the units DICOM defines.
def test_single_frame_rt_dose_is_scaled_by_dose_grid_scaling(tmp_path):
    import pydicom

    path = copied("pydicom", "data/test_files/rtdose_1frame.dcm", tmp_path)
    dataset = pydicom.dcmread(path)
    volume = volume_import.open_volume(path)
    expected = dataset.pixel_array * float(dataset.DoseGridScaling)
    np.testing.assert_allclose(values_of(volume)[0], expected, rtol=1e-6)
    assert float(values_of(volume).max()) == pytest.approx(1.254)
    assert volume.modality == "RTDOSE" and volume.units == "relative dose"   # its DoseUnits: RELATIVE


def test_rescale_slope_and_intercept_of_an_mr_slice(tmp_path):
    import pydicom

    path = copied("nibabel", "nicom/tests/data/decimal_rescale.dcm", tmp_path)
    dataset = pydicom.dcmread(path)
    expected = dataset.pixel_array * float(dataset.RescaleSlope) + float(dataset.RescaleIntercept)
    np.testing.assert_allclose(values_of(volume_import.open_volume(path))[0], expected, rtol=1e-6)


# Messages on the command line: exit 1, one line, no traceback, no library warning before it.
@pytest.mark.parametrize("package, shipped", [("pydicom", "data/test_files/badVR.dcm"),
                                              ("nibabel", "tests/data/test.mgz"),
                                              ("nibabel", "nicom/tests/data/0.dcm")])
def test_the_command_line_prints_one_line(tmp_path, package, shipped):
    path = copied(package, shipped, tmp_path)
    code, stdout, stderr = command_line(path, tmp_path)
    assert code == 1 and "wrote" not in stdout   # (Blender 5.3's bpy logs its colour config to stdout)
    assert stderr.startswith(f"pcvr: {path}: ") and stderr.count("\n") == 1, stderr


# 9 and 10. A detached NRRD header over a .nii.gz (the ITK and Slicer way to point at its voxels): pynrrd's
# own files (tests/convert/data/README.md).
PYNRRD_DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "pynrrd")


def ball(folder):
    """pynrrd's ball copied into `folder`, and its voxels as nibabel reads them, indexed [z, y, x]."""
    import nibabel

    for name in os.listdir(PYNRRD_DATA):
        shutil.copyfile(os.path.join(PYNRRD_DATA, name), os.path.join(str(folder), name))
    voxels = np.asarray(nibabel.load(os.path.join(str(folder), "BallBinary30x30x30.nii.gz")).dataobj)
    return np.transpose(voxels, (2, 1, 0)).astype(np.float32)


def test_a_positive_byte_skip_over_a_gzip_stream_counts_decompressed_bytes(tmp_path):
    expected = ball(tmp_path)
    with open(os.path.join(PYNRRD_DATA, "BallBinary30x30x30_nifti.nhdr")) as header:
        text = header.read()
    assert "# byte skip: -1\n" in text
    path = tmp_path / "ball_byteskip_352.nhdr"   # NIfTI-1's 352 bytes before the voxels, skipped
    path.write_text(text.replace("# byte skip: -1\n", "byte skip: 352\n"))
    volume = volume_import.open_volume(str(path))
    assert volume.shape == (30, 30, 30) and set(np.unique(expected)) == {0, 257}   # the ball: 257 (0x0101)
    np.testing.assert_array_equal(values_of(volume), expected)
    # Left-posterior-superior, unit steps: grid index [z, y, x].
    np.testing.assert_array_equal(volume.index_to_world, np.eye(4)[:, [2, 1, 0, 3]])
    # (pynrrd 1.1.3 seeks the byte skip in the compressed file as well, and fails on this header.)


def test_byte_skip_minus_one_over_a_gzip_stream_takes_its_last_bytes(tmp_path):
    import nrrd

    expected = ball(tmp_path)
    path = str(tmp_path / "BallBinary30x30x30_byteskip_minus_one_nifti.nhdr")
    np.testing.assert_array_equal(values_of(volume_import.open_volume(path)), expected)
    data, _header = nrrd.read(path)   # pynrrd reads it the same
    np.testing.assert_array_equal(np.transpose(data, (2, 1, 0)), expected)


def test_a_compressed_stream_of_another_size_than_the_header_says_is_refused(tmp_path):
    import nrrd

    ball(tmp_path)
    path = str(tmp_path / "BallBinary30x30x30_nifti.nhdr")
    data_file = str(tmp_path / "BallBinary30x30x30.nii.gz")
    assert refusal(path) == (f"{path}: its data file {data_file}: the gzip stream decompresses to 54352 bytes where "
                             "the header says 54000 (54000 bytes of int16 samples, 30 x 30 x 30), 352 bytes more: "
                             "the samples would be misplaced (a byte skip missing or wrong?)")
    with pytest.raises(nrrd.NRRDError, match="Size of the data does not equal"):
        nrrd.read(path)   # pynrrd refuses it too

    # A .nii.gz with bytes after its voxels: the same check.
    values = np.arange(24, dtype=np.int16).reshape(2, 3, 4)
    nifti = sf.nifti(str(tmp_path / "padded.nii.gz"), values, np.eye(4))
    with gzip.open(nifti) as packed:
        stream = packed.read()
    with gzip.open(nifti, "wb") as repacked:
        repacked.write(stream + b"\0" * 16)
    assert "the gzip stream decompresses to 416 bytes where the header says 400" in refusal(nifti)


# 8. TIFF pixels of several samples (axis S), as tifffile writes them.
def test_planar_rgb_tiff_is_refused_as_colour(tmp_path, rng):
    import tifffile

    path = str(tmp_path / "planar_rgb.tif")
    tifffile.imwrite(path, rng.integers(0, 255, size=(3, 9, 11)).astype(np.uint8), photometric="rgb",
                     planarconfig="separate")
    assert refusal(path).startswith(f"{path}: 3 samples per pixel (photometric RGB, planar, axes SYX (3, 9, 11)): "
                                    "colour or channels; only single-channel planes convert")


def test_a_small_stack_written_with_tifffiles_defaults_is_refused_with_the_way_to_write_it(tmp_path, rng):
    """tifffile.imwrite stores a (3 or 4, rows, columns) array as one page of RGB(A) samples in separate
    planes (its series axes SYX; it warns that this default will change to MINISBLACK pages). The file says
    colour, as Fiji and tifffile read it; so it is refused, saying how to write the planes as a stack."""
    import tifffile

    planes = rng.integers(-1000, 1000, size=(4, 9, 11)).astype(np.int16)
    path = str(tmp_path / "four_planes.tif")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        tifffile.imwrite(path, planes)
    with tifffile.TiffFile(path) as tif:
        assert tif.series[0].axes == "SYX" and len(tif.pages) == 1
    assert refusal(path) == (f"{path}: 4 samples per pixel (photometric RGB, planar, axes SYX (4, 9, 11)): colour "
                             "or channels; only single-channel planes convert; if they are 4 planes of a stack, as "
                             "tifffile.imwrite stores a (4, rows, columns) array by default, write it with "
                             "photometric='minisblack'")
    tifffile.imwrite(path, planes, photometric="minisblack")
    np.testing.assert_array_equal(values_of(volume_import.open_volume(path)), planes.astype(np.float32))


def test_a_truncated_tiff_is_one_line_with_tifffiles_log_folded_in(tmp_path, rng):
    """tifffile logs what it finds wrong (printed by Python's last-resort handler before our message); the
    converter holds it back and folds it into its one line."""
    import tifffile

    path = str(tmp_path / "truncated.tif")
    tifffile.imwrite(path, rng.integers(0, 4000, size=(5, 64, 64)).astype(np.uint16), photometric="minisblack")
    with open(path, "r+b") as handle:
        handle.truncate(handle.seek(0, 2) // 2)
    message = refusal(path)
    assert message.startswith(f"{path}: truncated: the series has 5 planes of 64 x 64, the file holds ")
    assert "(the reader warned: <tifffile.TiffPages @8> invalid page offset" in message
    code, _stdout, stderr = command_line(path, tmp_path)
    assert code == 1 and stderr == f"pcvr: {message}\n"
