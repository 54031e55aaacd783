# SPDX-License-Identifier: GPL-3.0-or-later

"""What a scan file is, from its name and its first bytes: the reader to open it with, or a refusal that
names the format and lists those that convert. A file is never read as another format than its own, and
never stands for other files beside it (a DICOM series is found from one of its own slices only).

    kind_of(path) -> "dicom" | "nifti" | "nrrd" | "metaimage" | "tiff", or raises ScanError
"""

import os
import zlib

from .volume import ScanError

# Suffixes of the formats read, longest first where one ends another.
FORMATS = {
    ".nii": "nifti", ".nii.gz": "nifti",
    ".nrrd": "nrrd", ".nhdr": "nrrd",
    ".mha": "metaimage", ".mhd": "metaimage",
    ".tif": "tiff", ".tiff": "tiff",
    ".dcm": "dicom", ".ima": "dicom",
}
SUPPORTED = ("DICOM (a folder, or one file of a series: single-frame slices or a Siemens mosaic), NIfTI "
             "(.nii, .nii.gz), NRRD (.nrrd, .nhdr), MetaImage (.mha, .mhd), TIFF (.tif, .tiff, or a folder of "
             ".tif planes)")

# Formats of scans and related data that are not read, by suffix: their names in messages.
NOT_READ = {
    ".mgz": "FreeSurfer MGH (.mgz)", ".mgh": "FreeSurfer MGH (.mgh)", ".mgh.gz": "FreeSurfer MGH (.mgh.gz)",
    ".mnc": "MINC (.mnc)", ".mnc.gz": "MINC (.mnc.gz)",
    ".par": "Philips PAR/REC (.PAR)", ".rec": "Philips PAR/REC (.REC)",
    ".head": "AFNI BRIK/HEAD (.HEAD)", ".brik": "AFNI BRIK/HEAD (.BRIK)", ".brik.gz": "AFNI BRIK/HEAD (.BRIK.gz)",
    ".img": "Analyze 7.5 or NIfTI pair image data (.img)", ".img.gz": "Analyze 7.5 or NIfTI pair image data",
    ".v": "ECAT 7 (.v)", ".mif": "MRtrix image (.mif)", ".mih": "MRtrix image header (.mih)",
    ".mif.gz": "MRtrix image (.mif.gz)", ".gii": "GIfTI surface (.gii)",
    ".trk": "TrackVis streamlines (.trk)", ".tck": "MRtrix streamlines (.tck)",
    ".vtk": "VTK (.vtk)", ".vti": "VTK image (.vti)", ".npy": "NumPy array (.npy)", ".npz": "NumPy arrays (.npz)",
    ".vdb": "OpenVDB (.vdb: open it directly, it needs no conversion)",
    ".blend": "Blender file (.blend)", ".zip": "zip archive (.zip: unpack it first)",
}
DICOM_PREAMBLE = 128


def _suffix_in(name, table):
    name = name.lower()
    return next((s for s in sorted(table, key=len, reverse=True) if name.endswith(s)), None)


def format_of(path):
    """The reader for `path` by its name alone: one of FORMATS' kinds, or None."""
    suffix = _suffix_in(path, FORMATS)
    return FORMATS[suffix] if suffix else None


def names_dicom_file(path):
    """Whether `path` is a file read as DICOM (by its suffix, or by its content when the suffix says nothing)."""
    if not os.path.isfile(path):
        return False
    kind = format_of(path)
    return kind == "dicom" or kind is None and _by_content(path, _head(path, DICOM_PREAMBLE + 4))[0] == "dicom"


def kind_of(path):
    """The reader for the file `path` (not a folder), from its suffix and, where the suffix says nothing or
    is shared with other formats, its content. Raises ScanError naming the format of a file not read."""
    kind = format_of(path)
    if kind is not None:
        return kind
    head = _head(path, 512)
    suffix = _suffix_in(path, {".hdr": 1, ".hdr.gz": 1})
    if suffix:
        _refuse(path, _analyze_header(head, suffix))
    suffix = _suffix_in(path, NOT_READ)
    if suffix:
        _refuse(path, NOT_READ[suffix])
    kind, what = _by_content(path, head)
    if kind is None:
        _refuse(path, what)
    return kind


def _refuse(path, what):
    raise ScanError(f"{path}: {what} is not a format this converter reads; it reads {SUPPORTED}")


def _head(path, count):
    try:
        with open(path, "rb") as handle:
            return handle.read(count)
    except OSError as ex:
        raise ScanError(f"{path}: cannot read the file: {ex.strerror or ex}") from None


def _analyze_header(head, suffix):
    """A .hdr: the header of a NIfTI-1 or NIfTI-2 pair, or of Analyze 7.5 (all with their data in an .img)."""
    if suffix == ".hdr.gz":
        head = _gunzip_head(head) or head
    if head[344:347] == b"ni1":
        return "the header of a NIfTI-1 pair (.hdr with its voxels in an .img; convert it to a single .nii)"
    if head[4:7] == b"ni2":
        return "the header of a NIfTI-2 pair (.hdr with its voxels in an .img; convert it to a single .nii)"
    if head[:4] in (b"\x5c\x01\x00\x00", b"\x00\x00\x01\x5c"):
        return "an Analyze 7.5 header (.hdr with its voxels in an .img; it holds no reliable orientation)"
    return "a .hdr file of unknown content (Analyze or NIfTI pairs have a 348-byte header)"


def _gunzip_head(head):
    """The first bytes of the gzip stream that `head` begins, as far as they decompress, or b""."""
    try:
        return zlib.decompressobj(31).decompress(head)
    except zlib.error:
        return b""


def _by_content(path, head):
    """(kind, None) for a format read, recognised by its magic; (None, its name) otherwise."""
    if head[DICOM_PREAMBLE:DICOM_PREAMBLE + 4] == b"DICM" or os.path.basename(path).upper() == "DICOMDIR":
        return "dicom", None
    if head.startswith(b"NRRD000"):
        return "nrrd", None
    if head[:4] in (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+"):
        return "tiff", None
    if head.split(b"=", 1)[0].strip() in (b"ObjectType", b"NDims"):
        return "metaimage", None
    if head.startswith(b"\x1f\x8b"):
        inner = _gunzip_head(head)
        if inner[344:347] == b"n+1" or inner[4:7] == b"n+2":
            return None, "a gzip-compressed NIfTI file without the .nii.gz suffix (rename it to .nii.gz)"
        return None, "gzip-compressed data of an unknown format"
    if head[344:347] == b"n+1" or head[4:7] == b"n+2":
        return None, "a NIfTI file without the .nii suffix (rename it to .nii)"
    if head.startswith(b"\x89HDF"):
        return None, "an HDF5 file (MINC-2 or other)"
    if head.startswith(b"CDF\x01") or head.startswith(b"CDF\x02"):
        return None, "a NetCDF file (MINC-1 or other)"
    if head.startswith(b"PK\x03\x04"):
        return None, "a zip archive (unpack it first)"
    name = os.path.basename(path)
    suffix = os.path.splitext(name)[1]
    return None, (f"a file of unknown format ('{suffix}', and its content is not DICOM, NRRD, MetaImage or TIFF)"
                  if suffix else "a file of unknown format (no suffix, and its content is not DICOM, NRRD, "
                                 "MetaImage or TIFF)")
