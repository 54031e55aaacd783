"""The benchmark's real CT head loader (tests/bench/ct_head_data.py) on small files made here: a Debian
archive holding an InVesalius project, unpacked and read as the benchmark reads the downloaded one."""

from __future__ import annotations

import io
import plistlib
import sys
import tarfile
from pathlib import Path

import numpy as np
import pytest

sys.path.append(str(Path(__file__).resolve().parents[1] / "bench"))
import ct_head_data  # noqa: E402


def tar_bytes(files: dict, mode: str) -> bytes:
    out = io.BytesIO()
    with tarfile.open(fileobj=out, mode=mode) as tar:
        for name, data in files.items():
            info = tarfile.TarInfo(name)
            info.size = len(data)
            tar.addfile(info, io.BytesIO(data))
    return out.getvalue()


def ar_bytes(members: dict) -> bytes:
    out = b"!<arch>\n"
    for name, data in members.items():
        out += f"{name + '/':<16}{0:<12}{0:<6}{0:<6}{'100644':<8}{len(data):<10}`\n".encode() + data
        out += b"\n" if len(data) % 2 else b""
    return out


def test_a_project_inside_a_package_comes_out_as_the_volume(tmp_path):
    slices = np.arange(3 * 4 * 5, dtype=np.int16).reshape(3, 4, 5) - 1024  # [slice, row, column]
    main = {"matrix": {"dtype": "int16", "filename": "matrix.dat", "shape": [3, 4, 5]},
            "spacing": [0.5, 0.5, 2.0], "name": "tiny"}
    project = tar_bytes({"tmp/main.plist": plistlib.dumps(main), "tmp/matrix.dat": slices.tobytes()}, "w:gz")
    deb = ar_bytes({"debian-binary": b"2.0\n", "control.tar.xz": tar_bytes({}, "w:xz"),
                    "data.tar.xz": tar_bytes({"./usr/share/doc/pkg/examples/Cranium.inv3": project}, "w:xz")})
    inv3 = tmp_path / "Cranium.inv3"
    inv3.write_bytes(ct_head_data.deb_member(deb, ct_head_data.MEMBER))
    values, index_to_world, meta = ct_head_data.load(inv3)
    assert values.shape == (5, 4, 3) and values.dtype == np.float32
    assert values[4, 2, 1] == slices[1, 2, 4]  # [i, j, k] = [column, row, slice]
    assert np.array_equal(np.diag(index_to_world), [0.5, 0.5, 2.0, 1.0])
    assert meta["name"] == "tiny"


def test_a_package_without_the_project_says_so():
    deb = ar_bytes({"data.tar.xz": tar_bytes({"./usr/share/doc/pkg/README": b"x"}, "w:xz")})
    with pytest.raises(ct_head_data.Unavailable, match="not found"):
        ct_head_data.deb_member(deb, ct_head_data.MEMBER)
    with pytest.raises(ct_head_data.Unavailable, match="not a Debian archive"):
        ct_head_data.deb_member(b"PK", ct_head_data.MEMBER)
