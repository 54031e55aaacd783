# SPDX-License-Identifier: GPL-3.0-or-later

"""DICOM series (one file per slice), read with pydicom: found in a folder (and its subfolders) by their
headers alone, sorted along the slice normal, checked, and read a slice at a time.

Values are the modality's physical units after each slice's RescaleSlope and RescaleIntercept (Hounsfield
units for CT), placed in DICOM's own patient space (LPS, millimetres). A gantry tilt keeps its exact
geometry: the slice step leans off the slice normal, and the grid's transform carries that shear. A
series with slices missing, or spacing that varies, is refused with the numbers rather than stretched.

Nothing that could identify a patient leaves this module: only geometry, modality, series numbers, sizes,
file paths and (to pick a series) series UIDs appear in messages and metadata.
"""

import os
from dataclasses import dataclass

import numpy as np

from . import dicom_mosaic
from .dicom_values import (header_number, orientation_of, physical_pixels, pixel_spacing, slice_thickness,
                           sop_class)
from .identify import SUPPORTED
from .volume import ScanError, ScanVolume, affine_from_axes

# The header fields the grouping and the geometry need: read without the pixel data.
HEADER_TAGS = ["SeriesInstanceUID", "SeriesNumber", "Modality", "ImagePositionPatient", "ImageOrientationPatient",
               "PixelSpacing", "Rows", "Columns", "NumberOfFrames", "SamplesPerPixel", "RescaleType", "Units",
               "SpacingBetweenSlices", "SliceThickness", "ImageType", "SOPClassUID", "DoseUnits"]
# Slice positions agree to this (mm), or this fraction of the slice spacing if larger: scanners round
# positions to a few decimals.
POSITION_TOLERANCE_MM = 0.01
POSITION_TOLERANCE_FRACTION = 0.01
# Orientation cosines agree to this between the slices of one series.
ORIENTATION_TOLERANCE = 1e-4
# Below this a slice step counts as along the normal (no gantry tilt), in degrees.
TILT_TOLERANCE_DEGREES = 0.01


@dataclass
class Series:
    uid: str
    number: object          # SeriesNumber, None when absent
    modality: str
    headers: list           # (path, pydicom Dataset without pixel data), one per slice file

    def summary(self, index):
        rows, columns = self.headers[0][1].get("Rows", "?"), self.headers[0][1].get("Columns", "?")
        number = "?" if self.number is None else self.number
        return (f"  [{index}] series {number}: {self.modality or '?'} {columns} x {rows}, "
                f"{len(self.headers)} slice(s), UID {self.uid}")


def find_series(path, skipped=None, subfolders=True):
    """The image series in the folder `path` (searched with its subfolders unless told not to), ordered by
    series number. `skipped` (a dict), when given, gets the files that are not slices, by what they are."""
    walk = os.walk(path) if subfolders else [(path, [], [name for name in os.listdir(path)
                                                          if os.path.isfile(os.path.join(path, name))])]
    files = sorted(os.path.join(folder, name) for folder, _dirs, names in walk
                   for name in names if not name.startswith(".") and name.upper() != "DICOMDIR")
    series = {}
    for file in files:
        try:
            header = _read_header(file)
        except ScanError:
            header = None
        reason = "not DICOM" if header is None else _not_a_slice(file, header)
        if reason:
            if skipped is not None:
                skipped.setdefault(reason, []).append(file)
            continue
        uid = str(header.get("SeriesInstanceUID", ""))
        if uid not in series:
            series[uid] = Series(uid=uid, number=header.get("SeriesNumber"),
                                 modality=str(header.get("Modality", "")), headers=[])
        series[uid].headers.append((file, header))
    return sorted(series.values(), key=lambda s: (s.number is None, _sortable(s.number), s.uid))


def _sortable(number):
    try:
        return float(number or 0)
    except (TypeError, ValueError):
        return 0.0


def _read_header(file):
    """The file's header without its pixel data; ScanError when pydicom cannot read it as DICOM."""
    from pydicom import dcmread
    from pydicom.errors import InvalidDicomError

    try:
        return dcmread(file, stop_before_pixels=True, specific_tags=HEADER_TAGS)
    except InvalidDicomError:
        raise ScanError(f"{file}: not a DICOM file (no 'DICM' marker after the 128-byte preamble)") from None
    except (OSError, ValueError, EOFError, KeyError, TypeError) as ex:
        raise ScanError(f"{file}: a malformed DICOM header ({type(ex).__name__}: {ex})") from None


def _not_a_slice(file, header):
    """Why `header` is no slice of a series (a sentence), or None. Siemens mosaics count as slices here:
    _volume unpacks them."""
    if header.get("ImagePositionPatient") is not None and header.get("ImageOrientationPatient") is not None:
        return None
    what = sop_class(header)
    if "Rows" not in header:
        return f"a DICOM {what}, which holds no image"
    frames = header_number(file, header, "NumberOfFrames", 1, int)
    if frames > 1 or "Enhanced" in what or "PerFrameFunctionalGroupsSequence" in header:
        return (f"a DICOM {what} (a multi-frame image whose geometry is given per frame, {frames} frame(s)), "
                "which does not convert")
    return f"a DICOM {what} without an image position and orientation (no slice of a volume)"


def choose_series(path, found, choice, skipped=None):
    """The series `choice` names (an index into `found` or a series UID); the only one when `choice` is None."""
    if not found:
        what = "; ".join(f"{len(files)} file(s): {reason} (e.g. {os.path.basename(files[0])})"
                         for reason, files in sorted((skipped or {}).items()))
        raise ScanError(f"{path}: no DICOM image series found (no file with an image position and orientation)"
                        f"{': ' + what if what else ''}. Supported: {SUPPORTED}")
    listing = "\n".join(s.summary(i) for i, s in enumerate(found))
    if choice is None:
        if len(found) == 1:
            return found[0]
        raise ScanError(f"{path}: {len(found)} series; pick one with --series INDEX or UID:\n{listing}")
    choice = str(choice)
    if choice.isdigit() and int(choice) < len(found):
        return found[int(choice)]
    for s in found:
        if s.uid == choice:
            return s
    raise ScanError(f"{path}: no series '{choice}'; the series are:\n{listing}")


def open_dicom(path, series=None):
    """A folder's series (the one `series` picks), or the series of the file `path` from its folder. A file
    that is no slice is refused with what it is: it never stands for other files beside it; a DICOMDIR
    names its folder's series."""
    if os.path.isdir(path) or os.path.basename(path).upper() == "DICOMDIR":
        folder = path if os.path.isdir(path) else os.path.dirname(path) or "."
        skipped = {}
        found = find_series(folder, skipped)
        return _volume(path, choose_series(path, found, series, skipped))
    header = _read_header(path)
    reason = _not_a_slice(path, header)
    if reason:
        raise ScanError(f"{path}: {reason}; DICOM converts as series of single-frame slices or Siemens mosaics")
    if dicom_mosaic.is_mosaic(header):
        return dicom_mosaic.open_mosaic(path, header, _units(header, str(header.get("Modality", ""))))
    uid = str(header.get("SeriesInstanceUID", ""))
    found = [s for s in find_series(os.path.dirname(path) or ".", subfolders=False) if s.uid == uid]
    return _volume(path, choose_series(path, found, series))


def _volume(path, series):
    headers = series.headers
    mosaics = [file for file, header in headers if dicom_mosaic.is_mosaic(header)]
    if mosaics and len(headers) == 1:
        file, header = headers[0]
        return dicom_mosaic.open_mosaic(file, header, _units(header, series.modality))
    if mosaics:
        raise ScanError(f"{path}: series {series.number} holds {len(headers)} Siemens mosaics, each a whole "
                        f"volume (time points or diffusion directions); convert one of its files, e.g. {mosaics[0]}")
    first = headers[0][1]
    for file, header in headers:
        frames = header_number(file, header, "NumberOfFrames", 1, int)
        if frames > 1:
            raise ScanError(f"{file}: a multi-frame {sop_class(header)} ({frames} frames); only "
                            "series of single-frame slices and Siemens mosaics convert")
        samples = header_number(file, header, "SamplesPerPixel", 1, int)
        if samples != 1:
            raise ScanError(f"{file}: {samples} samples per pixel (colour); only greyscale converts")
    _check_same(headers, "ImageOrientationPatient", lambda f, h: orientation_of(f, h),
                lambda a, b: np.allclose(a, b, atol=ORIENTATION_TOLERANCE))
    _check_same(headers, "Rows and Columns", lambda f, h: (header_number(f, h, "Rows", None, int),
                                                           header_number(f, h, "Columns", None, int)),
                lambda a, b: a == b)
    _check_same(headers, "PixelSpacing", lambda f, h: np.array(pixel_spacing(f, h)),
                lambda a, b: np.allclose(a, b, rtol=1e-6))
    _check_decoder(headers)

    along_row, along_column = orientation_of(headers[0][0], first)
    normal = np.cross(along_row, along_column)
    positions = np.array([header_number(f, h, "ImagePositionPatient", count=3) for f, h in headers])
    order = np.argsort(positions @ normal, kind="stable")
    files = [headers[n][0] for n in order]
    positions = positions[order]
    step, notes = _slice_step(files, positions, normal, first)

    row_spacing, column_spacing = pixel_spacing(headers[0][0], first)
    # i: slices in order along the normal, j: rows (down the columns), k: columns (along a row).
    index_to_world = affine_from_axes(np.column_stack([step, along_column * row_spacing,
                                                       along_row * column_spacing]), positions[0])
    modality = series.modality
    units = _units(first, modality)
    rows, columns = (header_number(headers[0][0], first, key, None, int) for key in ("Rows", "Columns"))
    if series.number is not None:
        notes["series_number"] = str(series.number)
    return ScanVolume(source=path, source_format="DICOM", shape=(len(files), rows, columns),
                      index_to_world=index_to_world, read_slabs=lambda: _read_slices(files),
                      modality=modality, units=units, notes=notes)


def _check_same(headers, name, value, same):
    reference_file, reference = headers[0][0], value(*headers[0])
    for file, header in headers[1:]:
        this = value(file, header)
        if this is None or None in np.ravel(this):
            raise ScanError(f"{file}: no {name}")
        if not same(this, reference):
            raise ScanError(f"{file}: its {name} differs from that of {reference_file} in the same series "
                            f"({_text(this)} against {_text(reference)}); the slices do not form one volume")


def _text(value):
    return " ".join(f"{v:g}" for v in np.ravel(value)) if not isinstance(value, tuple) else " x ".join(map(str, value))


def _slice_step(files, positions, normal, first):
    """The step from slice to slice (a 3-vector), checked: no two slices at one place, none missing, evenly
    spaced, on one line. A step off the normal is a gantry tilt, noted in degrees."""
    if len(files) == 1:
        thickness = slice_thickness(files[0], first)
        return normal * thickness, {"slice_spacing": "one slice: its thickness"}
    distances = positions @ normal
    gaps = np.diff(distances)
    # Missing slices only widen gaps, so the smallest gap is the series' spacing.
    smallest = float(gaps.min())
    tolerance = max(POSITION_TOLERANCE_MM, POSITION_TOLERANCE_FRACTION * abs(smallest))
    if smallest <= tolerance:
        n = int(np.argmin(gaps))
        raise ScanError(f"{files[n]} and {files[n + 1]}: two slices at the same position "
                        f"({distances[n]:.3f} mm along the normal); the series holds more than one volume "
                        "(several acquisitions, echoes or phases)")
    multiples = np.round(gaps / smallest)
    if np.all(np.abs(gaps - multiples * smallest) <= tolerance) and multiples.max() > 1:
        n = int(np.flatnonzero(multiples > 1)[0])
        raise ScanError(f"{files[n]} and {files[n + 1]}: {int(multiples[n]) - 1} slice(s) missing between "
                        f"positions {distances[n]:.3f} and {distances[n + 1]:.3f} mm (a gap of {gaps[n]:.3f} mm "
                        f"in a series spaced {smallest:.3f} mm)")
    uneven = np.flatnonzero(np.abs(gaps - smallest) > tolerance)
    if uneven.size:
        n = int(uneven[0])
        raise ScanError(f"{os.path.dirname(files[0]) or '.'}: slice spacing varies from {smallest:.3f} to "
                        f"{gaps.max():.3f} mm (first uneven gap {gaps[n]:.3f} mm, between {files[n]} and "
                        f"{files[n + 1]}); resample the series to even spacing first")
    step = (positions[-1] - positions[0]) / (len(files) - 1)
    off_line = np.linalg.norm(positions - (positions[0] + np.outer(np.arange(len(files)), step)), axis=1)
    if off_line.max() > tolerance:
        n = int(np.argmax(off_line))
        raise ScanError(f"{files[n]}: the slice lies {off_line[n]:.3f} mm off the line through the others; "
                        "the slices do not form one volume")
    notes = {}
    tilt = np.degrees(np.arccos(min(1.0, abs(step @ normal) / np.linalg.norm(step))))
    if tilt > TILT_TOLERANCE_DEGREES:
        notes["gantry_tilt_degrees"] = f"{tilt:.3f}"
    return step, notes


def _check_decoder(headers):
    """Refuse before reading any pixels when a compressed transfer syntax has no decoder installed."""
    from pydicom.pixels import get_decoder

    seen = set()
    for file, header in headers:
        syntax = getattr(header, "file_meta", {}).get("TransferSyntaxUID")
        if syntax is None or syntax in seen:
            continue
        seen.add(syntax)
        if not syntax.is_compressed:
            continue
        try:
            decoder = get_decoder(syntax)
        except NotImplementedError:
            raise ScanError(f"{file}: pixel data compressed as {syntax.name} ({syntax}), which pydicom cannot "
                            "decode") from None
        if not decoder.is_available:
            needs = "; ".join(decoder.missing_dependencies) or "a decoder plugin"
            raise ScanError(f"{file}: pixel data compressed as {syntax.name} ({syntax}) and no decoder for it is "
                            f"installed (needs {needs})")


def _units(header, modality):
    if modality == "CT":
        return "HU"
    if modality == "RTDOSE":
        return {"GY": "Gy", "RELATIVE": "relative dose"}.get(str(header.get("DoseUnits", "")).upper(), "")
    if modality == "PT" and header.get("Units"):
        return str(header.Units)
    rescale_type = str(header.get("RescaleType", ""))
    return "" if rescale_type in ("", "US") else rescale_type


def _read_slices(files):
    """One float32 slab [1, rows, columns] per file, in physical units."""
    for file in files:
        values, _dataset = physical_pixels(file)
        if values.ndim != 2:
            raise ScanError(f"{file}: pixel data of shape {values.shape} is not one greyscale slice")
        yield values.astype(np.float32)[np.newaxis]
