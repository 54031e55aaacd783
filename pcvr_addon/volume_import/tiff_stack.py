# SPDX-License-Identifier: GPL-3.0-or-later

"""Multi-page TIFF stacks, ImageJ hyperstacks and OME-TIFF, read with tifffile a slab of pages at a time;
and folders of single-plane TIFF files, one plane per file in the files' natural order (slice2 before slice10).

Voxel size from OME's PhysicalSize{X,Y,Z} (and units), else ImageJ's 'spacing' and 'unit' with the
XResolution and YResolution tags, else the resolution tags in inches or centimetres; without any, one
millimetre per voxel (recorded in the metadata). A stack has no patient: its axes are kept as they are,
x along a row, y down the columns, z through the planes (as ITK reads TIFF).
"""

import os
import re
import xml.etree.ElementTree as ElementTree

import numpy as np

from .volume import ScanError, ScanVolume, affine_from_axes, millimetres_per, planes_per_slab

# ResolutionUnit tag values: 2 inch, 3 centimetre (1: none, ImageJ's, whose unit is in its metadata).
MILLIMETRES_PER_RESOLUTION_UNIT = {2: 25.4, 3: 10.0}


def open_tiff(path, frame=None):
    import tifffile

    try:
        with tifffile.TiffFile(path) as tif:
            series = tif.series[0]
            axes, shape, dtype = series.axes, tuple(series.shape), np.dtype(series.dtype)
            spacing, spacing_note = _spacing(path, tif)
            samples = _samples_refusal(path, axes, shape, series.keyframe)
    except (tifffile.TiffFileError, OSError, IndexError) as ex:
        raise ScanError(f"{path}: not a readable TIFF file: {ex}") from None
    if dtype.kind not in "iuf":
        raise ScanError(f"{path}: samples of type {dtype} are not scalar numbers")
    if samples:
        raise ScanError(samples)
    if not axes.endswith("YX"):
        raise ScanError(f"{path}: pages of axes '{axes}' (colour samples?) are not single-channel planes")

    page_axes, page_shape = axes[:-2], shape[:-2]
    kept = [a for a, n in zip(page_axes, page_shape) if n > 1]
    if "C" in kept:
        raise ScanError(f"{path}: {shape[page_axes.index('C')]} channels; only single-channel stacks convert")
    time_axes = [a for a in kept if a == "T"]
    depth_axes = [a for a in kept if a != "T"]
    if len(depth_axes) > 1:
        raise ScanError(f"{path}: page axes '{page_axes}' {page_shape} hold more than one stack axis")
    frames = shape[page_axes.index("T")] if time_axes else 1
    if frames > 1 and frame is None:
        raise ScanError(f"{path}: a time series of {frames} stacks; pick one with --frame 0..{frames - 1}")
    frame = frame or 0
    if not 0 <= frame < frames:
        raise ScanError(f"{path}: --frame {frame} is outside the file's {frames} stack(s) (0..{frames - 1})")

    depth_axis = page_axes.index(depth_axes[0]) if depth_axes else None
    planes = shape[depth_axis] if depth_axis is not None else 1

    def page_index(z):
        index = [0] * len(page_shape)
        if depth_axis is not None:
            index[depth_axis] = z
        if time_axes:
            index[page_axes.index("T")] = frame
        return int(np.ravel_multi_index(index, page_shape)) if page_shape else 0

    rows, columns = shape[-2], shape[-1]

    def read_slabs():
        step = planes_per_slab(rows * columns)
        with tifffile.TiffFile(path) as tif:
            for first in range(0, planes, step):
                keys = [page_index(z) for z in range(first, min(planes, first + step))]
                try:
                    pages = tif.asarray(key=keys, series=0)
                except (ValueError, RuntimeError, NotImplementedError) as ex:  # e.g. a codec needing imagecodecs
                    raise ScanError(f"{path}: cannot decode pages {keys[0]}..{keys[-1]}: {ex}") from None
                except IndexError:
                    raise ScanError(f"{path}: truncated: the series has {planes} planes of {rows} x {columns}, the "
                                    f"file holds {len(tif.pages)} page(s)") from None
                yield pages.reshape(len(keys), rows, columns).astype(np.float32)

    sx, sy, sz = spacing
    index_to_world = affine_from_axes(np.array([[0, 0, sx], [0, sy, 0], [sz, 0, 0]], dtype=float), np.zeros(3))
    notes = {"spacing": spacing_note}
    if frames > 1:
        notes["frame"] = f"{frame} of {frames}"
    return ScanVolume(source=path, source_format="TIFF", shape=(planes, rows, columns),
                      index_to_world=index_to_world, read_slabs=read_slabs, notes=notes)


def _samples_refusal(path, axes, shape, page):
    """Why pixels of several samples (axis S: RGB, or channels stored as samples) do not convert, or None."""
    count = shape[axes.index("S")] if "S" in axes else 1
    if count == 1:
        return None
    photometric = getattr(page.photometric, "name", str(page.photometric))
    planar = int(page.planarconfig) == 2
    hint = ""
    if planar and photometric == "RGB" and count in (3, 4):
        hint = (f"; if they are {count} planes of a stack, as tifffile.imwrite stores a ({count}, rows, columns) "
                "array by default, write it with photometric='minisblack'")
    return (f"{path}: {count} samples per pixel (photometric {photometric}, {'planar' if planar else 'interleaved'}"
            f", axes {axes} {shape}): colour or channels; only single-channel planes convert{hint}")


def open_tiff_folder(folder, files):
    """`files` (TIFF files in `folder`), one plane each, stacked in natural name order."""
    import tifffile

    files = sorted(files, key=_natural_key)
    try:
        with tifffile.TiffFile(files[0]) as tif:
            shape, dtype = tuple(tif.series[0].shape), np.dtype(tif.series[0].dtype)
            spacing, spacing_note = _spacing(files[0], tif)
    except (tifffile.TiffFileError, OSError, IndexError) as ex:
        raise ScanError(f"{files[0]}: not a readable TIFF file: {ex}") from None
    if len(shape) != 2 or dtype.kind not in "iuf":
        raise ScanError(f"{files[0]}: a folder of TIFF files stacks single-plane greyscale images; this one "
                        f"holds {shape} {dtype}")

    def read_slabs():
        for file in files:
            try:
                plane = tifffile.imread(file)
            except (tifffile.TiffFileError, OSError, ValueError, RuntimeError) as ex:
                raise ScanError(f"{file}: cannot read the plane: {ex}") from None
            if plane.shape != shape:
                raise ScanError(f"{file}: a plane of {plane.shape}, where {files[0]} has {shape}")
            yield plane.astype(np.float32)[np.newaxis]

    sx, sy, sz = spacing
    index_to_world = affine_from_axes(np.array([[0, 0, sx], [0, sy, 0], [sz, 0, 0]], dtype=float), np.zeros(3))
    return ScanVolume(source=folder, source_format="TIFF", shape=(len(files), *shape),
                      index_to_world=index_to_world, read_slabs=read_slabs,
                      notes={"spacing": spacing_note, "planes": "one file each"})


def _natural_key(path):
    return [int(part) if part.isdigit() else part.lower() for part in re.split(r"(\d+)", os.path.basename(path))]


def _spacing(path, tif):
    """(x, y, z) voxel size in millimetres, and where it came from."""
    if tif.is_ome and tif.ome_metadata:
        pixels = next((e for e in ElementTree.fromstring(tif.ome_metadata).iter() if e.tag.endswith("Pixels")), None)
        if pixels is not None and "PhysicalSizeX" in pixels.attrib:
            size = [float(pixels.attrib.get(f"PhysicalSize{a}", pixels.attrib["PhysicalSizeX"])) *
                    millimetres_per(pixels.attrib.get(f"PhysicalSize{a}Unit", "µm"), path) for a in "XYZ"]
            return tuple(size), "OME PhysicalSize"
    page = tif.pages[0]
    resolution = [page.tags.get(name) for name in ("XResolution", "YResolution")]
    per_unit = [r.value[1] / r.value[0] if r is not None and r.value[0] else None for r in resolution]
    if tif.is_imagej and tif.imagej_metadata:
        meta = tif.imagej_metadata
        unit = millimetres_per(_imagej_unit(meta.get("unit", "")), path) if meta.get("unit") else 1.0
        xy = [s * unit if s else unit for s in per_unit]
        return (xy[0], xy[1], float(meta.get("spacing", 1.0)) * unit), "ImageJ"
    resolution_unit = page.tags.get("ResolutionUnit")
    scale = MILLIMETRES_PER_RESOLUTION_UNIT.get(int(resolution_unit.value) if resolution_unit else 0)
    if scale and all(per_unit):
        x, y = per_unit[0] * scale, per_unit[1] * scale
        return (x, y, x), "resolution tags (z spacing taken as x's)"
    return (1.0, 1.0, 1.0), "unknown, 1 mm per voxel assumed"


def _imagej_unit(unit):
    # ImageJ writes the micro sign escaped, and 'pixel' when it has no unit.
    unit = unit.replace("\\u00B5", "µ")
    return "" if unit in ("pixel", "pixels") else unit
