# SPDX-License-Identifier: GPL-3.0-or-later

"""A ScanVolume into a pcvr_native Grid and a .vdb, a slab at a time.

Memory: the sparse grid being built and one slab (volume.SLAB_BYTES, or one DICOM slice); the dense
array is never held. The background (the inactive value) is the volume's lowest value, found in a first
pass: the air and padding outside a CT's field of view (-1024 HU or below), zero in most MR and
microscopy, so that exactly those voxels cost nothing.
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


def to_grid(volume, background=None):
    """The volume as a pcvr_native.Grid named 'density' (background: the lowest value unless given)."""
    import pcvr_native as pn

    background = lowest_value(volume) if background is None else background
    try:
        return pn.Grid.from_slabs(volume.read_slabs(), volume.shape, volume.index_to_world, background=background)
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
