# SPDX-License-Identifier: GPL-3.0-or-later

"""Siemens mosaics: a whole volume in one DICOM frame, its slices laid out as tiles, row by row, in a
square of ceil(sqrt(n)) x ceil(sqrt(n)) tiles. The number of slices n is the Siemens CSA image header's
NumberOfImagesInMosaic (parsed by nibabel.nicom.csareader). Geometry as nibabel's MosaicWrapper defines it:
ImagePositionPatient is that of the whole frame's first pixel, so the first slice's first voxel lies half
the untiled margin further along the rows and columns; the slices follow one another along the slice
normal (its sign from the CSA header's SliceNormalVector) by SpacingBetweenSlices, else SliceThickness.
"""

import numpy as np

from .dicom_values import header_number, orientation_of, physical_pixels, pixel_spacing, slice_thickness
from .volume import ScanError, ScanVolume, affine_from_axes


def is_mosaic(header):
    image_type = header.get("ImageType") or []
    image_type = [image_type] if isinstance(image_type, str) else image_type
    return "MOSAIC" in (str(value).strip().upper() for value in image_type)


def _csa(file):
    """(NumberOfImagesInMosaic, SliceNormalVector or None) from the file's CSA image header."""
    from pydicom import dcmread
    from nibabel.nicom import csareader

    dataset = dcmread(file, stop_before_pixels=True)
    try:
        csa = csareader.get_csa_header(dataset)
        count = csareader.get_n_mosaic(csa) if csa else None
        normal = csareader.get_slice_normal(csa) if csa else None
    except (csareader.CSAReadError, KeyError, ValueError, TypeError, IndexError) as ex:
        raise ScanError(f"{file}: a Siemens mosaic whose CSA image header does not parse ({ex})") from None
    if not count:
        raise ScanError(f"{file}: a Siemens mosaic (ImageType MOSAIC) without NumberOfImagesInMosaic in its CSA "
                        "image header: its slices cannot be told apart")
    return int(count), normal


def open_mosaic(file, header, units):
    count, csa_normal = _csa(file)
    rows, columns = (header_number(file, header, key, None, int) for key in ("Rows", "Columns"))
    tiles = int(np.ceil(np.sqrt(count)))
    if not rows or not columns or rows % tiles or columns % tiles:
        raise ScanError(f"{file}: a Siemens mosaic of {count} images, which its {columns} x {rows} frame cannot "
                        f"hold as {tiles} x {tiles} equal tiles ({rows} and {columns} are not multiples of {tiles}:"
                        " its pixel data were cropped or resized?)")
    samples = header_number(file, header, "SamplesPerPixel", 1, int)
    if samples != 1:
        raise ScanError(f"{file}: {samples} samples per pixel (colour); only greyscale converts")
    tile_rows, tile_columns = rows // tiles, columns // tiles

    along_row, along_column = orientation_of(file, header)
    normal = np.cross(along_row, along_column)
    if csa_normal is not None and np.dot(csa_normal, normal) < 0:
        normal = -normal
    row_spacing, column_spacing = pixel_spacing(file, header)
    corner = np.array(header_number(file, header, "ImagePositionPatient", count=3))
    origin = (corner + along_column * row_spacing * (rows - tile_rows) / 2
              + along_row * column_spacing * (columns - tile_columns) / 2)
    # i: slices (tiles in order), j: rows, k: columns, as a series of slices.
    index_to_world = affine_from_axes(np.column_stack([normal * slice_thickness(file, header),
                                                       along_column * row_spacing, along_row * column_spacing]),
                                      origin)

    def read_slabs():
        values, _dataset = physical_pixels(file)
        if values.shape != (rows, columns):
            raise ScanError(f"{file}: pixel data of shape {values.shape}, where the header says {rows} x {columns}")
        slices = values.reshape(tiles, tile_rows, tiles, tile_columns).transpose(0, 2, 1, 3)
        yield slices.reshape(tiles * tiles, tile_rows, tile_columns)[:count].astype(np.float32)

    notes = {"mosaic": f"{count} images in {tiles} x {tiles} tiles"}
    if header.get("SeriesNumber") is not None:
        notes["series_number"] = str(header.get("SeriesNumber"))
    return ScanVolume(source=file, source_format="DICOM", shape=(count, tile_rows, tile_columns),
                      index_to_world=index_to_world, read_slabs=read_slabs,
                      modality=str(header.get("Modality", "")), units=units, notes=notes)
