"""A real CT head for the benchmarks, obtained as a Debian user would: `apt-get download invesalius-examples`.

| what     | value                                                                                       |
|----------|---------------------------------------------------------------------------------------------|
| source   | Debian's package ``invesalius-examples`` (InVesalius 3, Debian Med), file                   |
|          | ``examples/Cranium.inv3``: the study "ProMED CT 0051", a CT of a head                       |
| licence  | GPL-2 (the package's debian/copyright: ``Files: *``, Centro de Tecnologia da Informacao     |
|          | Renato Archer)                                                                              |
| volume   | 256 x 256 x 108 voxels, int16 Hounsfield units (-1024 .. 3033), voxels 0.957 x 0.957 x 1.5 mm |

An .inv3 file is a gzipped tar of an InVesalius project: ``main.plist`` names the scalar matrix
(``matrix.dat``, raw C-order [slice, row, column]), its dtype, shape and spacing. Nothing is committed:
the package is downloaded and unpacked into CACHE once (a few seconds, 19 MB), and `load()` raises
Unavailable with the reason where that cannot be done (no apt, no network), for the caller to report.
fetch_deb_member does the same for any file of any package (shaded_volumes.py's other volumes).
"""

from __future__ import annotations

import io
import os
import plistlib
import subprocess
import tarfile
import tempfile
from pathlib import Path

import numpy as np

PACKAGE = "invesalius-examples"
MEMBER = "examples/Cranium.inv3"
SOURCE = (f"Debian package `{PACKAGE}` (`apt-get download {PACKAGE}`), `{MEMBER}`: InVesalius' sample "
          "\"ProMED CT 0051\", a CT of a head; GPL-2 (the package's copyright file)")
CACHE = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "pcvr-bench" / "ct_head"
AIR_HU = -1024.0


class Unavailable(RuntimeError):
    """The CT head could not be obtained here (the message says why)."""


def deb_member(deb: bytes, name_suffix: str) -> bytes:
    """The file whose path ends with `name_suffix` inside a .deb (an ar archive holding data.tar.*)."""
    if not deb.startswith(b"!<arch>\n"):
        raise Unavailable("the downloaded package is not a Debian archive")
    pos = 8
    while pos + 60 <= len(deb):
        header = deb[pos:pos + 60]
        name, size = header[:16].decode().strip().rstrip("/"), int(header[48:58])
        body = deb[pos + 60:pos + 60 + size]
        if name.startswith("data.tar"):
            with tarfile.open(fileobj=io.BytesIO(body)) as tar:
                for member in tar.getmembers():
                    if member.name.endswith(name_suffix):
                        return tar.extractfile(member).read()
        pos += 60 + size + (size & 1)
    raise Unavailable(f"{name_suffix} not found in the package")


def fetch_deb_member(package: str, member: str, target: Path) -> Path:
    """`target`, unpacked from the file `member` of the Debian package `package` (`apt-get download`) when it
    is not there yet. Raises Unavailable saying why where that cannot be done."""
    if target.exists():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=target.parent) as tmp:
        try:
            proc = subprocess.run(["apt-get", "download", package], cwd=tmp, capture_output=True, text=True, timeout=300)
        except (OSError, subprocess.TimeoutExpired) as e:
            raise Unavailable(f"`apt-get download {package}` could not run: {e}") from e
        debs = list(Path(tmp).glob(f"{package}_*.deb"))
        if proc.returncode != 0 or not debs:
            tail = (proc.stderr.strip().splitlines() or ["no package file"])[-1]
            raise Unavailable(f"`apt-get download {package}` failed ({tail}); run `apt-get update` first if the "
                              "package lists are empty")
        try:
            data = deb_member(debs[0].read_bytes(), member)
        except Unavailable as e:
            raise Unavailable(f"{debs[0].name}: {e}") from None
        partial = Path(tmp) / target.name
        partial.write_bytes(data)
        partial.replace(target)  # whole or not at all
    return target


def load(inv3: Path | None = None):
    """(values [i, j, k] float32 in Hounsfield units, 4 x 4 index_to_world in mm, metadata dict), from
    `inv3` (an InVesalius project) or the cached download."""
    inv3 = inv3 or fetch_deb_member(PACKAGE, MEMBER, CACHE / "Cranium.inv3")
    with tarfile.open(inv3) as tar:
        members = {Path(m.name).name: m for m in tar.getmembers()}
        main = plistlib.loads(tar.extractfile(members["main.plist"]).read())
        matrix = main["matrix"]
        raw = tar.extractfile(members[matrix["filename"]]).read()
    slices = np.frombuffer(raw, dtype=np.dtype(matrix["dtype"])).reshape(matrix["shape"])  # [slice, row, column]
    values = np.ascontiguousarray(slices.transpose(2, 1, 0), dtype=np.float32)  # [column, row, slice] = [i, j, k]
    spacing = [float(s) for s in main["spacing"]]
    index_to_world = np.diag([*spacing, 1.0])
    return values, index_to_world, {"name": main.get("name", "?"), "shape": values.shape, "spacing": spacing,
                                    "source": SOURCE}
