"""Small scan files for the converter's tests, written with the libraries users' files come from (pydicom,
nibabel, pynrrd, tifffile; MetaImage by its documented header), each from an array and a geometry the
test keeps, so that what the converter reads can be compared with what made the file.

Patient fields are filled with marker strings (PATIENT_MARKERS) that must never reach a .vdb, a log or
an error."""

import os

import numpy as np

PATIENT_MARKERS = ("Doe^Jane", "PID-31415", "19700101", "Secret Hospital", "SECRET-SERIES-TEXT")


def dicom_series(folder, stored, origin=(0.0, 0.0, 0.0), row_direction=(1.0, 0.0, 0.0),
                 column_direction=(0.0, 1.0, 0.0), pixel_spacing=(1.0, 1.0), step=None, slope=1.0,
                 intercept=0.0, modality="CT", series_uid=None, series_number=1, transfer_syntax=None,
                 positions=None, rng=None):
    """Write `stored` (integer array [slice, row, column]) as one file per slice into `folder`, slice s at
    `origin + s * step` (default: 1 mm along the normal) or at `positions[s]`, files named and numbered in
    a shuffled order. Returns the files in slice order."""
    import pydicom
    from pydicom.dataset import Dataset, FileMetaDataset
    from pydicom.uid import CTImageStorage, ExplicitVRLittleEndian, MRImageStorage, generate_uid

    os.makedirs(folder, exist_ok=True)
    row_direction, column_direction = np.asarray(row_direction, float), np.asarray(column_direction, float)
    normal = np.cross(row_direction, column_direction)
    step = normal if step is None else np.asarray(step, float)
    if positions is None:
        positions = [np.asarray(origin, float) + s * step for s in range(stored.shape[0])]
    series_uid = series_uid or generate_uid()
    study_uid = generate_uid()
    order = (rng or np.random.default_rng(7)).permutation(stored.shape[0])
    files = []
    for s in range(stored.shape[0]):
        meta = FileMetaDataset()
        meta.MediaStorageSOPClassUID = CTImageStorage if modality == "CT" else MRImageStorage
        meta.MediaStorageSOPInstanceUID = generate_uid()
        meta.TransferSyntaxUID = transfer_syntax or ExplicitVRLittleEndian
        ds = Dataset()
        ds.file_meta = meta
        ds.SOPClassUID, ds.SOPInstanceUID = meta.MediaStorageSOPClassUID, meta.MediaStorageSOPInstanceUID
        ds.PatientName, ds.PatientID, ds.PatientBirthDate = PATIENT_MARKERS[0], PATIENT_MARKERS[1], PATIENT_MARKERS[2]
        ds.InstitutionName, ds.SeriesDescription = PATIENT_MARKERS[3], PATIENT_MARKERS[4]
        ds.StudyInstanceUID, ds.SeriesInstanceUID = study_uid, series_uid
        ds.Modality, ds.SeriesNumber, ds.InstanceNumber = modality, series_number, int(order[s]) + 1
        ds.ImagePositionPatient = [float(v) for v in positions[s]]
        ds.ImageOrientationPatient = [float(v) for v in (*row_direction, *column_direction)]
        ds.PixelSpacing = [float(v) for v in pixel_spacing]
        ds.RescaleSlope, ds.RescaleIntercept = slope, intercept
        ds.Rows, ds.Columns = stored.shape[1], stored.shape[2]
        ds.SamplesPerPixel, ds.PhotometricInterpretation = 1, "MONOCHROME2"
        ds.BitsAllocated, ds.BitsStored, ds.HighBit = 16, 16, 15
        ds.PixelRepresentation = 1 if stored.dtype.kind == "i" else 0
        if transfer_syntax is not None and transfer_syntax.is_compressed:
            from pydicom.encaps import encapsulate
            ds.PixelData = encapsulate([b"\xff\x4f\xff\x51 not really a codestream"])
            ds["PixelData"].VR = "OB"
            ds["PixelData"].is_undefined_length = True
        else:
            little_endian = "<i2" if stored.dtype.kind == "i" else "<u2"
            ds.PixelData = np.ascontiguousarray(stored[s].astype(little_endian)).tobytes()
        path = os.path.join(folder, f"IM{int(order[s]):04d}.dcm")
        pydicom.dcmwrite(path, ds, enforce_file_format=True)
        files.append(path)
    return files


def nifti(path, values, affine, slope=None, intercept=None):
    """`values` indexed [x, y, z(, t)] with the RAS `affine`, as nibabel writes it (.nii or .nii.gz)."""
    import nibabel

    image = nibabel.Nifti1Image(values, affine)
    image.header.set_xyzt_units("mm")
    if slope is not None:
        image.header.set_slope_inter(slope, intercept)
    image.to_filename(path)
    return path


def nrrd_file(path, values, directions, origin, space="right-anterior-superior", encoding="raw", detached=False):
    """`values` indexed [x, y, z] (x fastest on disk), axis a stepping by directions[a] in `space`."""
    import nrrd

    header = {"space": space, "space directions": np.asarray(directions, float),
              "space origin": np.asarray(origin, float), "encoding": encoding}
    nrrd.write(path, values, header, detached_header=detached)
    return path


def metaimage(path, values, spacing, origin, directions, compressed=False, detached=False):
    """`values` indexed [x, y, z] as a MetaImage: TransformMatrix lists each axis's direction in turn (ITK's
    order), Offset is voxel [0, 0, 0]'s centre."""
    import zlib

    data = np.asfortranarray(values).tobytes(order="F")
    if compressed:
        data = zlib.compress(data)
    element = {np.dtype(np.int16): "MET_SHORT", np.dtype(np.uint8): "MET_UCHAR",
               np.dtype(np.float32): "MET_FLOAT"}[values.dtype]
    data_file = os.path.splitext(os.path.basename(path))[0] + ".raw" if detached else "LOCAL"
    header = [
        "ObjectType = Image", "NDims = 3", "BinaryData = True", "BinaryDataByteOrderMSB = False",
        f"CompressedData = {compressed}", "TransformMatrix = " + " ".join(f"{v:.17g}" for v in np.ravel(directions)),
        "Offset = " + " ".join(f"{v:.17g}" for v in origin), "CenterOfRotation = 0 0 0",
        "AnatomicalOrientation = RAI", "ElementSpacing = " + " ".join(f"{v:.17g}" for v in spacing),
        "DimSize = " + " ".join(str(n) for n in values.shape), f"ElementType = {element}",
        f"ElementDataFile = {data_file}",
    ]
    text = ("\n".join(header) + "\n").encode()
    if detached:
        with open(os.path.join(os.path.dirname(path), data_file), "wb") as out:
            out.write(data)
        data = b""
    with open(path, "wb") as out:
        out.write(text + data)
    return path


def tiff_stack(path, values, spacing_um=None, ome=False):
    """`values` indexed [plane, row, column] as an ImageJ stack (spacing in micrometres: x, y, z) or an OME-TIFF."""
    import tifffile

    if ome:
        sx, sy, sz = spacing_um
        tifffile.imwrite(path, values, ome=True, metadata={
            "axes": "ZYX", "PhysicalSizeX": sx, "PhysicalSizeY": sy, "PhysicalSizeZ": sz,
            "PhysicalSizeXUnit": "µm", "PhysicalSizeYUnit": "µm", "PhysicalSizeZUnit": "µm"})
    elif spacing_um is None:
        tifffile.imwrite(path, values)
    else:
        sx, sy, sz = spacing_um
        tifffile.imwrite(path, values, imagej=True, resolution=(1 / sx, 1 / sy),
                         metadata={"spacing": sz, "unit": "um", "axes": "ZYX"})
    return path


def dense_values(grid, shape, background):
    """The grid's voxels over [0, shape) as a dense array, inactive ones at `background`."""
    out = np.full(shape, background, dtype=np.float32)
    if grid.active_voxel_count:
        (i0, j0, k0), (i1, j1, k1) = grid.index_bbox
        out[i0:i1 + 1, j0:j1 + 1, k0:k1 + 1] = grid.to_dense(fill=background)
    return out


def world(matrix, index):
    return (np.asarray(matrix) @ np.array([*index, 1.0]))[:3]
