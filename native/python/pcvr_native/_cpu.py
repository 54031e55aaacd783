"""Refuse to load a build the CPU cannot run, with a message instead of a crash.

The module is compiled for one x86-64 level (CMake's PCVR_ARCH; x86-64-v3, that is AVX2 and FMA, by
default). On a CPU without those instructions the first vector instruction, possibly while the
module is still loading, would kill the whole process: Blender included.
"""

from __future__ import annotations

from ._build import ARCH

# The instruction sets each -march level adds that this code uses.
_REQUIRED = {
    "x86-64": (),
    "x86-64-v2": ("sse4_2", "popcnt"),
    "x86-64-v3": ("sse4_2", "popcnt", "avx2", "fma", "bmi2"),
    "x86-64-v4": ("sse4_2", "popcnt", "avx2", "fma", "bmi2", "avx512f"),
}


def cpu_flags() -> set[str] | None:
    """The CPU's feature flags from /proc/cpuinfo, or None where that cannot be read."""
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as f:
            for line in f:
                if line.startswith("flags"):
                    return set(line.split(":", 1)[1].split())
    except OSError:
        return None
    return None


def check(flags: set[str] | None = None) -> None:
    """Raises ImportError when the CPU lacks an instruction set this build was compiled for."""
    flags = cpu_flags() if flags is None else flags
    if flags is None or ARCH not in _REQUIRED:  # unknown: "native" builds, or no /proc
        return
    missing = [f for f in _REQUIRED[ARCH] if f not in flags]
    if missing:
        raise ImportError(
            f"pcvr_native was built for {ARCH}, but this CPU lacks {', '.join(missing)}: rebuild it "
            "for older CPUs with `pip wheel ./native --config-settings=cmake.define.PCVR_ARCH=x86-64`")
