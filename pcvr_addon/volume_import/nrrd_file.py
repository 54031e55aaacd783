# SPDX-License-Identifier: GPL-3.0-or-later

"""NRRD (.nrrd, and .nhdr with detached data): pynrrd parses the header; the voxels stream through
raw_stream (raw, gzip, bzip2), so only one slab is held. Geometry from 'space directions' and 'space
origin' (or 'spacings'), brought to LPS from the file's 'space'."""

import os

import numpy as np

from . import raw_stream
from .volume import ScanError, ScanVolume, affine_from_axes, millimetres_per, reversed_axes

# NRRD's type names (the spec's synonyms) to numpy.
_TYPES = {
    np.int8: ("signed char", "int8", "int8_t"),
    np.uint8: ("uchar", "unsigned char", "uint8", "uint8_t"),
    np.int16: ("short", "short int", "signed short", "signed short int", "int16", "int16_t"),
    np.uint16: ("ushort", "unsigned short", "unsigned short int", "uint16", "uint16_t"),
    np.int32: ("int", "signed int", "int32", "int32_t"),
    np.uint32: ("uint", "unsigned int", "uint32", "uint32_t"),
    np.int64: ("longlong", "long long", "long long int", "signed long long", "signed long long int",
               "int64", "int64_t"),
    np.uint64: ("ulonglong", "unsigned long long", "unsigned long long int", "uint64", "uint64_t"),
    np.float32: ("float",),
    np.float64: ("double",),
}
NUMPY_TYPE = {name: np.dtype(numpy_type) for numpy_type, names in _TYPES.items() for name in names}

ENCODINGS = {"raw": "raw", "gzip": "gzip", "gz": "gzip", "bzip2": "bzip2", "bz2": "bzip2"}

# Diagonal of the matrix from a NRRD space to LPS; spaces without a patient keep their axes.
SPACE_TO_LPS = {
    "left-posterior-superior": (1, 1, 1), "lps": (1, 1, 1),
    "right-anterior-superior": (-1, -1, 1), "ras": (-1, -1, 1),
    "left-anterior-superior": (1, -1, 1), "las": (1, -1, 1),
    "scanner-xyz": (1, 1, 1), "3d-right-handed": (1, 1, 1),
}


def open_nrrd(path):
    import nrrd

    try:
        with open(path, "rb") as handle:
            header = nrrd.read_header(handle)
            data_offset = handle.tell()
    except (nrrd.NRRDError, UnicodeDecodeError, ValueError) as ex:
        raise ScanError(f"{path}: not a readable NRRD header: {ex}") from None

    shape = tuple(int(n) for n in header["sizes"])
    if len(shape) != 3:
        raise ScanError(f"{path}: a {len(shape)}-D NRRD; only 3-D volumes convert")
    type_name = str(header["type"]).lower()
    if type_name not in NUMPY_TYPE:
        raise ScanError(f"{path}: voxel type '{header['type']}' is not a scalar number type")
    dtype = NUMPY_TYPE[type_name]
    if dtype.itemsize > 1:
        dtype = dtype.newbyteorder("<" if header.get("endian", "little") == "little" else ">")
    encoding = str(header["encoding"]).lower()
    if encoding not in ENCODINGS:
        raise ScanError(f"{path}: encoding '{header['encoding']}' is not supported (raw, gzip or bzip2 are)")

    data_path = path
    detached = header.get("data file") or header.get("datafile")
    if detached:
        if not isinstance(detached, str) or detached.startswith("LIST") or " " in detached.strip():
            raise ScanError(f"{path}: data split over several files ('{detached}') is not supported")
        data_path = os.path.join(os.path.dirname(path), detached)
        if not os.path.isfile(data_path):
            raise ScanError(f"{path}: its data file '{data_path}' does not exist")
        data_offset = 0
    data_offset += _skip_lines(data_path, data_offset, int(header.get("line skip", 0)))
    # The byte skip counts bytes of the decompressed stream when the data are compressed (teem's and pynrrd's
    # reading); -1: the samples are the data's last bytes.
    byte_skip = int(header.get("byte skip", 0))
    compression = ENCODINGS[encoding]
    if byte_skip < -1:
        raise ScanError(f"{path}: 'byte skip: {byte_skip}' is invalid (-1 or more)")
    skip = None if byte_skip == -1 else byte_skip
    if compression == "raw":
        data_bytes = int(np.prod(shape)) * dtype.itemsize
        data_offset = os.path.getsize(data_path) - data_bytes if skip is None else data_offset + skip
        skip = 0
    layout = raw_stream.RawLayout(path=data_path, offset=skip, file_offset=data_offset, compression=compression,
                                  dtype=dtype, shape=shape, header=path if detached else "")
    return ScanVolume(source=path, source_format="NRRD", shape=shape[::-1],
                      index_to_world=reversed_axes(_index_to_world(path, header)),
                      read_slabs=lambda: raw_stream.read_slabs(layout))


def _skip_lines(data_path, offset, lines):
    if lines <= 0:
        return 0
    with open(data_path, "rb") as handle:
        handle.seek(offset)
        for _ in range(lines):
            handle.readline()
        return handle.tell() - offset


def _index_to_world(path, header):
    if "space directions" in header:
        directions = np.asarray(header["space directions"], dtype=float)
        if directions.shape != (3, 3) or not np.all(np.isfinite(directions)):
            raise ScanError(f"{path}: 'space directions' must give a 3-D step for each of the 3 axes")
        origin = np.asarray(header.get("space origin", np.zeros(3)), dtype=float)
        space = str(header.get("space", "3d-right-handed")).lower()
        if space not in SPACE_TO_LPS:
            raise ScanError(f"{path}: space '{header.get('space')}' is not a 3-D patient or scanner space")
        units = header.get("space units", ["mm"] * 3)
        scale = np.array([millimetres_per(unit, path) for unit in units])
        if len(set(scale)) != 1:
            raise ScanError(f"{path}: space units differ between axes ({', '.join(units)})")
        to_lps = np.array(SPACE_TO_LPS[space], dtype=float) * scale[0]
        # pynrrd gives one row per axis; columns of index_to_world are the axes' steps.
        return affine_from_axes((directions * to_lps).T, origin * to_lps)
    spacings = np.asarray(header.get("spacings", [1.0, 1.0, 1.0]), dtype=float)
    if spacings.shape != (3,) or not np.all(np.isfinite(spacings)) or np.any(spacings == 0):
        raise ScanError(f"{path}: 'spacings' must give 3 finite, non-zero spacings")
    return affine_from_axes(np.diag(spacings), np.zeros(3))
