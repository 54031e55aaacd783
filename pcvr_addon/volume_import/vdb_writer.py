# SPDX-License-Identifier: GPL-3.0-or-later

"""A ScanVolume into a pcvr_native Grid and a .vdb, a slab at a time.

Memory: the sparse grid being built and one slab (volume.SLAB_BYTES, or one DICOM slice); the dense
array is never held. The background (the inactive value) is the volume's lowest value, found in a first
pass: the air and padding outside a CT's field of view (-1024 HU or below), zero in most MR and
microscopy, so that exactly those voxels cost nothing. NaN, which NIfTI and TIFF writers use for "no data",
becomes the background too (the count is kept in the metadata); infinity is refused.
"""

import numpy as np

from .volume import ScanError


def lowest_value(volume):
    lowest = np.inf
    for slab in volume.read_slabs():
        if slab.size:
            lowest = min(lowest, float(np.nanmin(slab)))
    if not np.isfinite(lowest):
        raise ScanError(f"{volume.source}: the volume has no finite values")
    return lowest


def _nan_as(slabs, background, volume):
    """The slabs with NaN replaced by `background`; their count noted on `volume`."""
    count = 0
    for slab in slabs:
        nan = np.isnan(slab)
        if nan.any():
            count += int(nan.sum())
            slab = np.where(nan, np.float32(background), slab)
        yield slab
    if count:
        volume.notes["nan_voxels_as_background"] = str(count)


def to_grid(volume, background=None):
    """The volume as a pcvr_native.Grid named 'density' (background: the lowest value unless given)."""
    import pcvr_native as pn

    background = lowest_value(volume) if background is None else background
    try:
        return pn.Grid.from_slabs(_nan_as(volume.read_slabs(), background, volume), volume.shape,
                                  volume.index_to_world, background=background)
    except pn.GridError as ex:
        raise ScanError(f"{volume.source}: {ex}") from None


def write_vdb(volume, output):
    """Write the volume to the .vdb `output` as the grid 'density' with its metadata; the file is replaced
    whole or not at all (pcvr_native writes beside it and renames)."""
    grid = to_grid(volume)
    try:
        grid.write_vdb(output, "density", metadata=volume.metadata())
    except OSError as ex:
        raise ScanError(str(ex)) from None


def convert(path, output, series=None, frame=None):
    """Convert the scan at `path` to the .vdb `output`. Returns the ScanVolume."""
    from . import open_volume

    volume = open_volume(path, series=series, frame=frame)
    write_vdb(volume, output)
    return volume
