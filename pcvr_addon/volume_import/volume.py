# SPDX-License-Identifier: GPL-3.0-or-later

"""A scan opened for conversion: its size, where its voxels lie, its units, and its values a slab at a time.

World convention: every format is brought to DICOM's patient coordinates, LPS, in millimetres: +x towards
the patient's left, +y towards the back (posterior), +z towards the head (superior). In Blender (right-handed,
Z up) a patient scanned lying down then stands upright, facing Blender's front view (-Y), seen from the
front with the patient's left on the image's right, as radiologists show it. NIfTI's RAS and NRRD's
right-anterior-superior spaces are turned a half turn about z into it; MetaImage is already LPS (ITK's
physical space); a TIFF stack, which has no patient, keeps its own axes: x along a row, y down the
columns, z through the planes.

Grid index order: i runs over the slowest axis of the file (DICOM slices, the last axis of NIfTI, NRRD
and MetaImage, TIFF planes), so that a slab of i-planes is read in one sequential pass and handed to
pcvr_native.Grid.from_slabs without the whole array ever being held.
"""

import logging
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Callable, Iterator

import numpy as np

# Slabs of about this many bytes of float32: large enough that per-slab overhead vanishes (a 512 x 512
# plane is 1 MiB), small beside any volume worth streaming: the margin a conversion needs above the grid.
SLAB_BYTES = 4 << 20

# Length units to millimetres, by the names the formats use (NIfTI's xyzt_units through nibabel,
# NRRD's space units, ImageJ's and OME's units).
MILLIMETRES_PER_UNIT = {
    "mm": 1.0, "millimeter": 1.0, "millimetre": 1.0,
    "m": 1000.0, "meter": 1000.0, "metre": 1000.0,
    "cm": 10.0, "centimeter": 10.0,
    "um": 1e-3, "µm": 1e-3, "μm": 1e-3, "micron": 1e-3, "micrometer": 1e-3, "micrometre": 1e-3,
    "nm": 1e-6, "nanometer": 1e-6,
}

# RAS (NIfTI, NRRD's right-anterior-superior) to LPS: x and y change sign.
LPS_FROM_RAS = np.diag([-1.0, -1.0, 1.0, 1.0])


# Where a converted scan lies: its grid's `pcvr_world` metadata.
SCAN_WORLD = "LPS millimetres"

class ScanError(Exception):
    """A scan that cannot be converted; the message names the file and the cause."""


@dataclass
class ScanVolume:
    """A scan, opened but not read: `read_slabs()` yields float32 arrays [n, shape[1], shape[2]] of i-planes
    in order, in the scan's physical units, and can be called more than once."""

    source: str                    # the file or directory, as named in messages
    source_format: str             # "DICOM", "NIfTI", "NRRD", "MetaImage", "TIFF"
    shape: tuple                   # (i, j, k)
    index_to_world: np.ndarray     # 4x4, world = M @ [i, j, k, 1], LPS millimetres
    read_slabs: Callable[[], Iterator[np.ndarray]]
    modality: str = ""             # DICOM's modality ("CT", "MR", ...), "" when unknown
    units: str = ""                # of the values: "HU" for CT, "" when unknown
    notes: dict = field(default_factory=dict)  # further patient-free facts (e.g. gantry tilt)

    @property
    def spacing(self):
        """Distance between neighbouring voxel centres along i, j and k, in millimetres."""
        return tuple(float(np.linalg.norm(self.index_to_world[:3, a])) for a in range(3))

    def description(self):
        modality = f"{self.modality} " if self.modality else ""
        size = " x ".join(str(n) for n in self.shape)
        spacing = " x ".join(f"{s:.4g}" for s in self.spacing)
        return f"{modality}{self.source_format} volume, {size} voxels of {spacing} mm"

    def metadata(self):
        """String metadata for the .vdb: nothing from the scan that could identify a patient."""
        meta = {
            "pcvr_source_format": self.source_format,
            "pcvr_world": SCAN_WORLD,
            "pcvr_description": self.description(),
        }
        if self.modality:
            meta["pcvr_modality"] = self.modality
        if self.units:
            meta["pcvr_units"] = self.units
        meta.update({f"pcvr_{key}": str(value) for key, value in self.notes.items()})
        return meta


# Loggers of the format libraries that print to stderr (nibabel's own handler; tifffile's records through
# Python's last-resort handler) or could.
LIBRARY_LOGGERS = ("nibabel", "nibabel.global", "tifffile", "pydicom")


class _Held(logging.Handler):
    def __init__(self):
        super().__init__(logging.WARNING)
        self.messages = []

    def emit(self, record):
        self.messages.append(record.getMessage())


@contextmanager
def held_warnings(fold=True):
    """The format libraries' warnings and log records held back, not printed: with `fold`, a ScanError
    raised inside carries their first lines (once each); otherwise, and when the file reads, they are
    dropped. DICOM does not fold: pydicom's warnings can quote header values, which may identify a patient
    (our own message names the field at fault)."""
    held = _Held()
    loggers = [logging.getLogger(name) for name in LIBRARY_LOGGERS]
    saved = [(logger.handlers, logger.propagate) for logger in loggers]
    for logger in loggers:
        logger.handlers, logger.propagate = [held], False
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            yield
    except ScanError as ex:
        said = []
        for text in [str(w.message) for w in caught] + held.messages if fold else ():
            lines = text.strip().splitlines()
            if lines and lines[0] not in said:
                said.append(lines[0])
        if not said:
            raise
        raise ScanError(f"{ex} (the reader warned: {'; '.join(said[:3])})") from None
    finally:
        for logger, (handlers, propagate) in zip(loggers, saved):
            logger.handlers, logger.propagate = handlers, propagate


def quietly(read_slabs, fold=True):
    """`read_slabs` (a ScanVolume's) with each slab read under held_warnings."""
    def read():
        slabs = read_slabs()
        while True:
            with held_warnings(fold):
                slab = next(slabs, None)
            if slab is None:
                return
            yield slab
    return read


def planes_per_slab(plane_voxels):
    return max(1, SLAB_BYTES // (4 * max(1, plane_voxels)))


def millimetres_per(unit, source):
    """Millimetres per `unit` (a length unit name; empty: millimetres)."""
    if not unit:
        return 1.0
    key = unit.strip().lower()
    if key not in MILLIMETRES_PER_UNIT:
        raise ScanError(f"{source}: unknown length unit '{unit}'")
    return MILLIMETRES_PER_UNIT[key]


def affine_from_axes(directions, origin):
    """The 4x4 matrix whose columns are the three axis steps `directions` (3x3, one step per column) and `origin`."""
    m = np.eye(4)
    m[:3, :3] = directions
    m[:3, 3] = origin
    return m


def reversed_axes(m):
    """index_to_world for the same voxels indexed in the reverse axis order ([k, j, i] of a file's [i, j, k])."""
    return m[:, [2, 1, 0, 3]]
