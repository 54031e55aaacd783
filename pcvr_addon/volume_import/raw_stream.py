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
    offset: int             # bytes before the first sample, in the decompressed stream (NIfTI's .gz, NRRD's
                            # byte skip); None: the samples are the stream's last bytes (NRRD's byte skip -1)
    compression: str        # one of COMPRESSIONS ("gzip" also reads zlib streams, as NRRD writers vary)
    dtype: np.dtype         # with its byte order
    shape: tuple            # (nx, ny, nz), x fastest
    slope: float = 1.0      # physical value = stored * slope + intercept
    intercept: float = 0.0
    file_offset: int = 0    # bytes of the file before the (compressed) stream: a header in plain text
    stream_bytes: int = None  # a compressed stream's whole decompressed size; None: offset and the samples
    header: str = ""        # the header file that names `path`, when another (for messages)


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


def _where(layout):
    return f"{layout.header}: its data file {layout.path}" if layout.header else layout.path


def _open(layout, offset, raw):
    """The stream of samples from the file `raw` (open; closed by the caller: gzip and bz2 leave it open)."""
    raw.seek(layout.file_offset)
    if layout.compression == "raw":
        raw.seek(layout.file_offset + offset)
        return raw
    if layout.compression == "bzip2":
        stream = bz2.BZ2File(raw)
    elif layout.compression == "gzip":
        stream = gzip.GzipFile(fileobj=raw) if _is_gzip(raw) else io.BufferedReader(_ZlibReader(raw))
    elif layout.compression == "zlib":
        stream = io.BufferedReader(_ZlibReader(raw))
    else:
        raise ScanError(f"{layout.path}: compression '{layout.compression}' is not one of {', '.join(COMPRESSIONS)}")
    _skip(stream, offset)
    return stream


def _is_gzip(raw):
    start = raw.tell()
    magic = raw.read(2)
    raw.seek(start)
    return magic == b"\x1f\x8b"


def _skip(stream, count=None):
    """Read past `count` bytes (all that are left when None); returns how many there were."""
    done = 0
    while count is None or done < count:
        chunk = stream.read(1 << 20 if count is None else min(count - done, 1 << 20))
        if not chunk:
            break
        done += len(chunk)
    return done


def read_slabs(layout, first_plane=0, planes=None):
    """Yield float32 slabs [n, ny, nx] of z-planes first_plane .. first_plane + planes (default: to the end).
    Raises ScanError naming the file when it holds fewer samples than the layout says, or when a
    compressed stream read to its last plane decompresses to another size than the header says (samples
    shifted by bytes the header does not skip would otherwise convert silently)."""
    nx, ny, nz = layout.shape
    planes = nz - first_plane if planes is None else planes
    plane_bytes = nx * ny * layout.dtype.itemsize
    step = planes_per_slab(nx * ny)
    try:
        offset = layout.offset if layout.offset is not None else _offset_from_end(layout, nz * plane_bytes)
        with open(layout.path, "rb") as raw, _open(layout, offset, raw) as stream:
            _skip(stream, first_plane * plane_bytes)
            done = 0
            while done < planes:
                count = min(step, planes - done)
                buffer = stream.read(count * plane_bytes)
                if len(buffer) < count * plane_bytes:
                    expected = (first_plane + planes) * plane_bytes
                    got = (first_plane + done) * plane_bytes + len(buffer)
                    raise ScanError(f"{_where(layout)}: truncated: the header promises {expected} bytes of "
                                    f"{layout.dtype.name} samples ({nx} x {ny} x {nz}), the file ends after {got}")
                slab = _physical(np.frombuffer(buffer, dtype=layout.dtype).reshape(count, ny, nx),
                                 layout.slope, layout.intercept)
                del buffer  # not held while the next slab is read
                yield slab
                done += count
            if layout.compression != "raw" and layout.offset is not None and first_plane + planes == nz:
                _check_size(layout, offset + nz * plane_bytes + _skip(stream), plane_bytes)
    except (OSError, EOFError, zlib.error) as ex:
        raise ScanError(f"{_where(layout)}: cannot read the voxels ({layout.compression}): {ex}") from None


def _offset_from_end(layout, data_bytes):
    """Where the samples start when they are the decompressed stream's last bytes: one pass to count them."""
    with open(layout.path, "rb") as raw, _open(layout, 0, raw) as stream:
        size = _skip(stream)
    if size < data_bytes:
        raise ScanError(f"{_where(layout)}: truncated: the header promises {data_bytes} bytes of "
                        f"{layout.dtype.name} samples, the {layout.compression} stream holds {size}")
    return size - data_bytes


def _check_size(layout, found, plane_bytes):
    nx, ny, nz = layout.shape
    data = nz * plane_bytes
    expected = layout.stream_bytes if layout.stream_bytes is not None else layout.offset + data
    if found == expected:
        return
    parts = [f"{layout.offset} bytes skipped"] if layout.offset else []
    parts.append(f"{data} bytes of {layout.dtype.name} samples, {nx} x {ny} x {nz}")
    if expected > layout.offset + data:
        parts.append("the other frames")
    difference = f"{abs(found - expected)} bytes {'more' if found > expected else 'fewer'}"
    raise ScanError(f"{_where(layout)}: the {layout.compression} stream decompresses to {found} bytes where the "
                    f"header says {expected} ({', '.join(parts)}), {difference}: the samples would be misplaced "
                    "(a byte skip missing or wrong?)")


def _physical(samples, slope, intercept):
    if slope == 1.0 and intercept == 0.0:
        return samples.astype(np.float32)
    # In double, a plane at a time (no double copy of the slab), so that integer samples and integer
    # rescales (CT's) give exact float32 values.
    out = np.empty(samples.shape, dtype=np.float32)
    for plane, stored in zip(out, samples):
        plane[...] = stored * slope + intercept
    return out
