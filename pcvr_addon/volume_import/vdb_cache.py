# SPDX-License-Identifier: GPL-3.0-or-later

"""Where a scan's .vdb goes when the user names none (render INPUT, File > Import), and reuse of it.

A conversion is identified by the scan's absolute path, the size and modification time of every file
under it, the series and frame picked and this converter's version: rendering the same scan again
converts nothing, and a changed file converts afresh.
"""

import hashlib
import os
import re

from . import open_volume, write_vdb
from .identify import names_dicom_file

# Bump when the conversion's output changes, so that older cached files are not reused.
CONVERTER_VERSION = 2


def cache_directory():
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "pcvr", "scans")


def _fingerprint(path, series, frame):
    digest = hashlib.sha1(f"{CONVERTER_VERSION}\0{os.path.abspath(path)}\0{series}\0{frame}".encode())
    if names_dicom_file(path):
        path = os.path.dirname(os.path.abspath(path))  # a file names its folder's series
    files = [path] if os.path.isfile(path) else sorted(
        os.path.join(folder, name) for folder, _dirs, names in os.walk(path) for name in names)
    for file in files:
        status = os.stat(file)
        digest.update(f"\0{file}\0{status.st_size}\0{status.st_mtime_ns}".encode())
    return digest.hexdigest()[:16]


def vdb_name(path):
    """A file name for the scan's .vdb that Blender will not take for a numbered sequence: a DICOM series is
    named after its folder."""
    if names_dicom_file(path):
        path = os.path.dirname(os.path.abspath(path))
    stem = os.path.basename(os.path.normpath(path))
    stem = re.sub(r"(\.nii)?\.[A-Za-z]+$", "", stem) or "scan"
    return re.sub(r"[^A-Za-z0-9_-]+", "_", stem) + "_volume.vdb"


def cached_vdb(path, series=None, frame=None, directory=None):
    """The .vdb of the scan at `path`, converted unless an up-to-date one exists. Returns (vdb path,
    ScanVolume); raises ScanError."""
    directory = directory or cache_directory()
    target = os.path.join(directory, _fingerprint(path, series, frame), vdb_name(path))
    volume = open_volume(path, series=series, frame=frame)
    if not os.path.isfile(target):
        os.makedirs(os.path.dirname(target), exist_ok=True)
        write_vdb(volume, target)
    return target, volume
