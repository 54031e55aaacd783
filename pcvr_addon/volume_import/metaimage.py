# SPDX-License-Identifier: GPL-3.0-or-later

"""MetaImage (.mha with the data inline, .mhd with a detached data file), read with a reader of our own.

The header is a few lines of `Key = value` text ending at ElementDataFile; the voxels stream through
raw_stream (raw, or zlib when CompressedData is True). A reader of ~100 lines instead of SimpleITK
(~50 MB of native code per Python version inside the extension) for one simple format. Geometry is ITK's:
Offset is the first voxel's centre, ElementSpacing the spacing, and TransformMatrix lists each axis's
direction (axis 0's three cosines first), in LPS millimetres, as ITK writes it.
"""

import os

import numpy as np

from . import raw_stream
from .volume import ScanError, ScanVolume, affine_from_axes, reversed_axes

ELEMENT_TYPES = {
    "MET_CHAR": np.int8, "MET_UCHAR": np.uint8, "MET_SHORT": np.int16, "MET_USHORT": np.uint16,
    "MET_INT": np.int32, "MET_UINT": np.uint32, "MET_LONG": np.int32, "MET_ULONG": np.uint32,
    "MET_LONG_LONG": np.int64, "MET_ULONG_LONG": np.uint64, "MET_FLOAT": np.float32, "MET_DOUBLE": np.float64,
}
# Older synonyms written by some tools.
SYNONYMS = {"ElementSize": "ElementSpacing", "Origin": "Offset", "Position": "Offset",
            "Rotation": "TransformMatrix", "Orientation": "TransformMatrix"}
MAX_HEADER_BYTES = 1 << 16


def read_header(path):
    """The header's fields as strings, and the byte offset just past the ElementDataFile line."""
    fields, offset = {}, 0
    with open(path, "rb") as handle:
        for raw_line in iter(lambda: handle.readline(MAX_HEADER_BYTES), b""):
            offset += len(raw_line)
            line = raw_line.decode("latin-1").strip()
            if not line:
                continue
            key, equals, value = line.partition("=")
            if not equals:
                raise ScanError(f"{path}: not a MetaImage header: line '{line[:40]}' is not 'Key = value'")
            key = SYNONYMS.get(key.strip(), key.strip())
            fields[key] = value.strip()
            if key == "ElementDataFile":
                return fields, offset
            if offset > MAX_HEADER_BYTES:
                break
    raise ScanError(f"{path}: not a MetaImage header: no ElementDataFile line")


def _numbers(path, fields, key, count, default=None):
    if key not in fields:
        if default is None:
            raise ScanError(f"{path}: the header has no {key}")
        return np.asarray(default, dtype=float)
    try:
        values = np.array([float(v) for v in fields[key].split()])
    except ValueError:
        raise ScanError(f"{path}: {key} = '{fields[key]}' is not {count} numbers") from None
    if values.size != count or not np.all(np.isfinite(values)):
        raise ScanError(f"{path}: {key} must hold {count} finite numbers, it holds '{fields[key]}'")
    return values


def open_metaimage(path):
    fields, header_end = read_header(path)
    if fields.get("ObjectType", "Image") != "Image":
        raise ScanError(f"{path}: ObjectType is '{fields['ObjectType']}', not an image")
    if fields.get("NDims") != "3":
        raise ScanError(f"{path}: NDims = {fields.get('NDims')}; only 3-D volumes convert")
    if int(fields.get("ElementNumberOfChannels", "1")) != 1:
        raise ScanError(f"{path}: {fields['ElementNumberOfChannels']} channels per voxel; only scalar volumes convert")
    element_type = fields.get("ElementType")
    if element_type not in ELEMENT_TYPES:
        raise ScanError(f"{path}: ElementType '{element_type}' is not one of {', '.join(ELEMENT_TYPES)}")
    big_endian = (fields.get("BinaryDataByteOrderMSB") or fields.get("ElementByteOrderMSB", "False")) == "True"
    dtype = np.dtype(ELEMENT_TYPES[element_type]).newbyteorder(">" if big_endian else "<")

    shape = tuple(int(n) for n in _numbers(path, fields, "DimSize", 3))
    if min(shape) < 1:
        raise ScanError(f"{path}: DimSize {' '.join(map(str, shape))} is empty")
    spacing = _numbers(path, fields, "ElementSpacing", 3, default=[1.0, 1.0, 1.0])
    origin = _numbers(path, fields, "Offset", 3, default=[0.0, 0.0, 0.0])
    directions = _numbers(path, fields, "TransformMatrix", 9, default=np.eye(3).ravel()).reshape(3, 3)

    data_file = fields["ElementDataFile"]
    if data_file == "LOCAL":
        data_path, offset = path, header_end
    elif data_file.startswith("LIST") or "%" in data_file or " " in data_file:
        raise ScanError(f"{path}: data split over several files ('{data_file}') is not supported")
    else:
        data_path = os.path.join(os.path.dirname(path), data_file)
        if not os.path.isfile(data_path):
            raise ScanError(f"{path}: its data file '{data_path}' does not exist")
        offset = int(fields.get("HeaderSize", "0"))
        if offset == -1:  # the data are the file's last bytes
            offset = os.path.getsize(data_path) - int(np.prod(shape)) * dtype.itemsize
    compressed = fields.get("CompressedData", "False") == "True"
    layout = raw_stream.RawLayout(path=data_path, offset=0, file_offset=offset,
                                  compression="zlib" if compressed else "raw", dtype=dtype, shape=shape,
                                  header="" if data_file == "LOCAL" else path)
    # Row a of `directions` is axis a's direction; columns of index_to_world are the axes' steps.
    index_to_world = affine_from_axes(directions.T * spacing, origin)
    return ScanVolume(source=path, source_format="MetaImage", shape=shape[::-1],
                      index_to_world=reversed_axes(index_to_world),
                      read_slabs=lambda: raw_stream.read_slabs(layout),
                      modality=_modality(fields), notes={})


def _modality(fields):
    # MetaImage's Modality field: MET_MOD_CT, MET_MOD_MR, ...
    value = fields.get("Modality", "")
    return value[len("MET_MOD_"):] if value.startswith("MET_MOD_") and value != "MET_MOD_UNKNOWN" else ""
