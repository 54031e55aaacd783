# SPDX-License-Identifier: GPL-3.0-or-later

"""Scans into OpenVDB: DICOM series, NIfTI, NRRD, MetaImage and TIFF stacks become a float grid `density`
in the scan's physical units (Hounsfield units for CT), placed in LPS millimetres (see volume.py).

    volume = open_volume(path, series=None, frame=None)   # reads headers only
    convert(path, output, series=None, frame=None)        # writes output (.vdb), returns the ScanVolume

The format libraries (pydicom, nibabel, pynrrd, tifffile) are imported only when a file of theirs is opened.
"""

import os

from .volume import SCAN_WORLD, ScanError, ScanVolume, held_warnings, quietly  # noqa: F401 (SCAN_WORLD, ScanVolume: public names)
from .vdb_writer import convert, to_grid, write_vdb  # noqa: F401

# A folder of TIFF files is a stack of planes; any other folder is searched for DICOM series; a file is read
# as the format its suffix and content say (identify.py), or refused.
from .identify import FORMATS, SUPPORTED, format_of, kind_of  # noqa: F401
# File > Import's filter.
FILE_PATTERNS = ";".join(f"*{suffix}" for suffix in FORMATS)


def is_scan(path):
    """Whether the command line should convert `path` (anything but a .vdb or a .blend)."""
    return not path.lower().endswith((".vdb", ".blend"))


def open_volume(path, series=None, frame=None):
    """Open a scan for conversion (headers only). `series` picks a DICOM series (index or UID), `frame` a
    volume of a 4-D NIfTI or a time series of TIFF stacks. Raises ScanError naming the file and the cause."""
    if not os.path.exists(path):
        raise ScanError(f"{path}: no such file or folder")
    tiff_files = _tiff_folder(path)
    kind = "tiff" if tiff_files else "dicom" if os.path.isdir(path) else kind_of(path)
    if series is not None and kind != "dicom":
        raise ScanError(f"{path}: --series picks a DICOM series; this is a {kind} file")
    if frame is not None and kind not in ("nifti", "tiff"):
        raise ScanError(f"{path}: --frame picks a volume of a 4-D NIfTI or TIFF time series; this is a {kind} "
                        "file or series")
    with held_warnings(fold=kind != "dicom"):
        volume = _open(path, kind, series, frame, tiff_files)
    volume.read_slabs = quietly(volume.read_slabs, fold=kind != "dicom")
    return volume


def _open(path, kind, series, frame, tiff_files):
    if kind == "dicom":
        from .dicom_series import open_dicom
        return open_dicom(path, series)
    if kind == "nifti":
        from .nifti import open_nifti
        return open_nifti(path, frame)
    if kind == "nrrd":
        from .nrrd_file import open_nrrd
        return open_nrrd(path)
    if kind == "metaimage":
        from .metaimage import open_metaimage
        return open_metaimage(path)
    from .tiff_stack import open_tiff, open_tiff_folder
    if tiff_files:
        if frame is not None:
            raise ScanError(f"{path}: --frame picks a volume of a 4-D file; this is a folder of TIFF planes")
        return open_tiff_folder(path, tiff_files)
    return open_tiff(path, frame)


def _tiff_folder(path):
    """The files of a folder that holds TIFF files only (hidden files aside), else None."""
    if not os.path.isdir(path):
        return None
    files = [os.path.join(path, name) for name in os.listdir(path)
             if not name.startswith(".") and os.path.isfile(os.path.join(path, name))]
    return files if files and all(format_of(f) == "tiff" for f in files) else None
