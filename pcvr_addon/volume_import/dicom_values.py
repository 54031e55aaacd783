# SPDX-License-Identifier: GPL-3.0-or-later

"""DICOM values the converter reads, checked: numeric header fields (a malformed one is a ScanError naming
the file, the field and its text; header text of fields we do not read never reaches a message), and a
file's pixels in the modality's physical units, as DICOM defines them: stored * RescaleSlope +
RescaleIntercept, and for RT dose stored * DoseGridScaling (grays, or relative dose); and the geometry a slice's
header gives (orientation, pixel spacing, slice spacing), which series and mosaics both place by."""

import numpy as np

from .volume import ScanError


def header_number(file, header, keyword, default=None, kind=float, count=None):
    """The header's numeric field `keyword` (`count` numbers when given), `default` when absent or empty;
    ScanError naming the file, the field and its text when it is not a number."""
    value = header.get(keyword)
    if value is None or value == "":
        return default
    values = list(value) if count is not None else [value]
    try:
        numbers = [float(v) for v in values]
        if kind is int and any(n != int(n) for n in numbers):
            raise ValueError
        numbers = [kind(n) for n in numbers]
    except (TypeError, ValueError, OverflowError):
        text = "\\".join(str(v) for v in values)
        raise ScanError(f"{file}: a malformed DICOM header: {keyword} '{text}' is not "
                        f"{'a whole number' if kind is int else 'a number'}"
                        f"{'' if count is None else ' list'}") from None
    if count is not None and len(numbers) != count:
        raise ScanError(f"{file}: a malformed DICOM header: {keyword} holds {len(numbers)} numbers, not {count}")
    return numbers if count is not None else numbers[0]


def sop_class(header):
    """What the object is, by its SOP class: 'Enhanced MR Image Storage', 'RT Plan Storage', ..."""
    uid = header.get("SOPClassUID") or getattr(header, "file_meta", {}).get("MediaStorageSOPClassUID")
    name = getattr(uid, "name", "") if uid else ""
    return name if name and name != str(uid) else f"object of SOP class {uid}" if uid else "object"


def physical_pixels(file):
    """The file's pixel array (as pydicom decodes it, any shape) in physical units, float64, and its dataset."""
    from pydicom import dcmread

    try:
        dataset = dcmread(file)
        stored = dataset.pixel_array
    except Exception as ex:  # pydicom's decoders raise many types; the message names no patient
        raise ScanError(f"{file}: cannot read its pixel data: {type(ex).__name__}: {ex}") from None
    slope = header_number(file, dataset, "RescaleSlope", 1.0) or 1.0
    intercept = header_number(file, dataset, "RescaleIntercept", 0.0)
    dose_scaling = header_number(file, dataset, "DoseGridScaling", 1.0) or 1.0
    # In double: integer stored values and integer rescales (CT's) give exact Hounsfield units.
    return (stored.astype(np.float64) * slope + intercept) * dose_scaling, dataset


def orientation_of(file, header):
    """The unit directions along a row and down a column (ImageOrientationPatient's two halves)."""
    orientation = np.array(header_number(file, header, "ImageOrientationPatient", count=6))
    along_row, along_column = orientation[:3], orientation[3:]
    lengths = np.linalg.norm(along_row), np.linalg.norm(along_column)
    if min(lengths) < 1e-6:
        raise ScanError(f"{file}: a malformed DICOM header: ImageOrientationPatient has a zero direction")
    return along_row / lengths[0], along_column / lengths[1]


def pixel_spacing(file, header):
    """(row spacing, column spacing) in millimetres: PixelSpacing, 1 mm when absent."""
    return tuple(header_number(file, header, "PixelSpacing", [1.0, 1.0], count=2))


def slice_thickness(file, header):
    """SpacingBetweenSlices, else SliceThickness, else 1 mm."""
    return (header_number(file, header, "SpacingBetweenSlices") or header_number(file, header, "SliceThickness")
            or 1.0)
