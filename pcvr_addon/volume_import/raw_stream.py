# SPDX-License-Identifier: GPL-3.0-or-later

"""Voxels stored as one block of samples, first axis fastest (NIfTI, NRRD, MetaImage), read a slab of
last-axis planes at a time from the plain or compressed file: one sequential pass, one slab in memory.

A file's [x, y, z] (x fastest) read as C-order [z, y, x]: grid index i is the file's z, as volume.py says.
"""

import bz2
import gzip
import io
import zlib
from dataclasses import dataclass

import numpy as np

from .volume import ScanError, planes_per_slab

COMPRESSIONS = ("raw", "gzip", "bzip2", "zlib")


@dataclass
class RawLayout:
    path: str               # the file holding the samples
    offset: int             # bytes before the first sample, in the decompressed stream (NIfTI's .gz)
    compression: str        # one of COMPRESSIONS ("gzip" also reads zlib streams, as NRRD writers vary)
    dtype: np.dtype         # with its byte order
    shape: tuple            # (nx, ny, nz), x fastest
    slope: float = 1.0      # physical value = stored * slope + intercept
    intercept: float = 0.0
    file_offset: int = 0    # bytes of the file before the (compressed) stream: a header in plain text


class _ZlibReader(io.RawIOBase):
    """A file-like view of a zlib (or gzip: wbits 47 detects either) stream, decompressed as read."""

    def __init__(self, raw):
        self._raw = raw
        self._inflate = zlib.decompressobj(47)
        self._pending = b""

    def readable(self):
        return True

    def readinto(self, buffer):
        while not self._pending:
            chunk = self._raw.read(1 << 20)
            if not chunk:
                self._pending = self._inflate.flush()
                if not self._pending:
                    return 0
                break
            self._pending = self._inflate.decompress(chunk)
        n = min(len(buffer), len(self._pending))
        buffer[:n] = self._pending[:n]
        self._pending = self._pending[n:]
        return n

    def close(self):
        self._raw.close()
        super().close()


def _open(layout):
    raw = open(layout.path, "rb")
    raw.seek(layout.file_offset)
    if layout.compression == "raw":
        raw.seek(layout.file_offset + layout.offset)
        return raw
    if layout.compression == "bzip2":
        stream = bz2.BZ2File(raw)
    elif layout.compression == "gzip":
        stream = gzip.GzipFile(fileobj=raw) if _is_gzip(raw) else io.BufferedReader(_ZlibReader(raw))
    elif layout.compression == "zlib":
        stream = io.BufferedReader(_ZlibReader(raw))
    else:
        raw.close()
        raise ScanError(f"{layout.path}: compression '{layout.compression}' is not one of {', '.join(COMPRESSIONS)}")
    _skip(stream, layout.offset)
    return stream


def _is_gzip(raw):
    start = raw.tell()
    magic = raw.read(2)
    raw.seek(start)
    return magic == b"\x1f\x8b"


def _skip(stream, count):
    while count > 0:
        chunk = stream.read(min(count, 1 << 20))
        if not chunk:
            break
        count -= len(chunk)


def read_slabs(layout, first_plane=0, planes=None):
    """Yield float32 slabs [n, ny, nx] of z-planes first_plane .. first_plane + planes (default: to the end).
    Raises ScanError naming the file when it holds fewer samples than the layout says."""
    nx, ny, nz = layout.shape
    planes = nz - first_plane if planes is None else planes
    plane_bytes = nx * ny * layout.dtype.itemsize
    step = planes_per_slab(nx * ny)
    try:
        with _open(layout) as stream:
            _skip(stream, first_plane * plane_bytes)
            done = 0
            while done < planes:
                count = min(step, planes - done)
                buffer = stream.read(count * plane_bytes)
                if len(buffer) < count * plane_bytes:
                    expected = (first_plane + planes) * plane_bytes
                    got = (first_plane + done) * plane_bytes + len(buffer)
                    raise ScanError(f"{layout.path}: truncated: the header promises {expected} bytes of "
                                    f"{layout.dtype.name} samples ({nx} x {ny} x {nz}), the file ends after {got}")
                slab = _physical(np.frombuffer(buffer, dtype=layout.dtype).reshape(count, ny, nx),
                                 layout.slope, layout.intercept)
                del buffer  # not held while the next slab is read
                yield slab
                done += count
    except (OSError, EOFError, zlib.error) as ex:
        raise ScanError(f"{layout.path}: cannot read the voxels ({layout.compression}): {ex}") from None


def _physical(samples, slope, intercept):
    if slope == 1.0 and intercept == 0.0:
        return samples.astype(np.float32)
    # In double, a plane at a time (no double copy of the slab), so that integer samples and integer
    # rescales (CT's) give exact float32 values.
    out = np.empty(samples.shape, dtype=np.float32)
    for plane, stored in zip(out, samples):
        plane[...] = stored * slope + intercept
    return out
