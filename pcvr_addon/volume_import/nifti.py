# SPDX-License-Identifier: GPL-3.0-or-later

"""NIfTI-1 and NIfTI-2 (.nii, .nii.gz): nibabel reads the header and the affine (sform, else qform, RAS);
the voxels stream through raw_stream, so a .nii.gz is decompressed once, in one pass."""

import numpy as np

from . import raw_stream
from .volume import LPS_FROM_RAS, ScanError, ScanVolume, millimetres_per, reversed_axes


def open_nifti(path, frame=None):
    import nibabel

    try:
        image = nibabel.load(path)
    except Exception as ex:  # nibabel raises several types for a file that is not NIfTI
        raise ScanError(f"{path}: not a readable NIfTI file: {ex}") from None
    if not isinstance(image, (nibabel.Nifti1Image, nibabel.Nifti2Image)):
        raise ScanError(f"{path}: not a single-file NIfTI image (.nii or .nii.gz)")
    header = image.header
    shape = tuple(int(n) for n in image.shape)
    dtype = header.get_data_dtype()
    if dtype.fields is not None or dtype.kind not in "iuf":
        raise ScanError(f"{path}: voxels of type {dtype} (RGB or complex) are not a scalar volume")

    volume_bytes = int(np.prod(shape[:3])) * dtype.itemsize
    frames = int(np.prod(shape[3:])) if len(shape) > 3 else 1
    if len(shape) < 3 or len(shape) > 4:
        raise ScanError(f"{path}: a {len(shape)}-D image; only 3-D and 4-D (one volume per frame) convert")
    if frames > 1 and frame is None:
        raise ScanError(f"{path}: a 4-D image of {frames} volumes; pick one with --frame 0..{frames - 1}")
    frame = frame or 0
    if not 0 <= frame < frames:
        raise ScanError(f"{path}: --frame {frame} is outside the image's {frames} volume(s) (0..{frames - 1})")

    # On load nibabel moves scl_slope and scl_inter from the header to the image's array proxy.
    slope, intercept = image.dataobj.slope, image.dataobj.inter
    spatial_unit, _time_unit = header.get_xyzt_units()
    scale = millimetres_per("" if spatial_unit == "unknown" else spatial_unit, path)
    layout = raw_stream.RawLayout(
        path=path, offset=int(image.dataobj.offset) + frame * volume_bytes,
        compression="gzip" if path.lower().endswith(".gz") else "raw", dtype=dtype, shape=shape[:3],
        slope=float(slope), intercept=float(intercept),
        stream_bytes=int(image.dataobj.offset) + frames * volume_bytes)

    lps = LPS_FROM_RAS @ image.affine
    lps[:3, :] *= scale
    notes = {"frame": f"{frame} of {frames}"} if frames > 1 else {}
    return ScanVolume(source=path, source_format="NIfTI", shape=shape[2::-1], index_to_world=reversed_axes(lps),
                      read_slabs=lambda: raw_stream.read_slabs(layout), notes=notes)
