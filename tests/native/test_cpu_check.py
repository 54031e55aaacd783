"""The module refuses, with a message, to load on a CPU that lacks the instructions it was built
for, instead of killing the process (Blender included) at the first one."""

from __future__ import annotations

import pytest

import pcvr_native
from pcvr_native import _build, _cpu


def test_build_records_its_instruction_set_level():
    assert _build.ARCH  # from CMake's PCVR_ARCH


def test_this_cpu_passes_the_check():
    _cpu.check()  # importing pcvr_native above already did; calling again must not raise
    assert pcvr_native.render_xray


@pytest.mark.skipif(not _cpu._REQUIRED.get(_build.ARCH), reason="a build without extra instruction sets")
def test_a_cpu_without_them_gets_an_import_error_naming_them():
    with pytest.raises(ImportError) as err:
        _cpu.check({"fpu", "sse2"})
    message = str(err.value)
    assert _build.ARCH in message and "PCVR_ARCH" in message
    for flag in _cpu._REQUIRED[_build.ARCH]:
        assert flag in message


def test_unknown_flags_or_levels_do_not_block_loading(monkeypatch):
    """Without /proc/cpuinfo, or for a build for the build machine itself (-march=native), there is
    nothing to compare, and loading goes ahead."""
    monkeypatch.setattr(_cpu, "cpu_flags", lambda: None)
    _cpu.check()
    monkeypatch.setattr(_cpu, "ARCH", "native")
    _cpu.check({"fpu"})
