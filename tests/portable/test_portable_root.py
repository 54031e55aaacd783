"""The extension zip on a Linux without the build machine's libraries: a Debian 13 root file system
(`make test-portable` makes it; tools/portable_root.sh) with Python 3.13 and bpy, but no OpenVDB, oneTBB,
Boost or Blosc. There the zip installs as Blender installs it, Blender picks its cp313 wheel, and F12 and
`python -m pcvr_addon render` give the images they give here, with the same bpy."""

import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import bpy
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent
PORTABLE_ROOT = Path(os.environ.get("PCVR_PORTABLE_ROOT", ROOT / "build" / "debian13-root")).resolve()
# What render_here.py needs besides bpy and the archive.
HELPERS = [HERE / "render_here.py", ROOT / "tests/addon/install_extension.py",
           ROOT / "tests/addon/blender_scenes.py", ROOT / "tests/addon/lit_scenes.py"]
# The libraries whose absence the root stands for (Debian 12's packages the module was linked with).
BUILD_MACHINE_LIBRARIES = ["libopenvdb", "libtbb", "libboost_iostreams", "libblosc", "liblog4cplus", "libImath"]

# Same wheel, same bpy, same CPU: only the system's glibc (2.36 here, 2.41 there, libm among it) and
# libstdc++ differ. Measured: F12 in X-ray and shaded and the command line's shaded EXR the same to the
# bit; the command line's X-ray EXR the same in its XRay and alpha channels, its RGB (1 - exp(-gain *
# integral), through libm's expm1) 6e-8 apart, one float32 step below 1. 1e-6 allows a few steps, far
# below any visible change and far above what a wrong library or a changed render would give.
TOLERANCE = 1e-6

pytestmark = pytest.mark.skipif(not (PORTABLE_ROOT / ".stamp").is_file(),
                                reason=f"no root file system at {PORTABLE_ROOT}: `make test-portable` makes it")


def archive():
    with open(ROOT / "blender_manifest.toml", "rb") as fh:
        manifest = tomllib.load(fh)
    return ROOT / "dist" / f"{manifest['id']}-{manifest['version']}-linux_x64.zip"


def root_bpy_version():
    [dist_info] = PORTABLE_ROOT.glob("opt/venv/lib/python3*/site-packages/bpy-*.dist-info")
    return dist_info.name.removeprefix("bpy-").removesuffix(".dist-info")


def prepare(work):
    """WORK with the archive, render_here.py and its helpers: what both runs get."""
    (work / "tools").mkdir(parents=True)
    shutil.copy2(archive(), work / "pcvr.zip")
    for helper in HELPERS:
        shutil.copy2(helper, work / helper.name)
    shutil.copy2(ROOT / "tools" / "ct_head.py", work / "tools" / "ct_head.py")


def render(python, work, inside_root=False):
    """render_here.py in a fresh process, here or in the root (where `work` is the path seen inside)."""
    environment = dict(os.environ, BLENDER_USER_RESOURCES=str(work / "blender"), PYTHONPATH=str(work))
    command = [python, str(work / "render_here.py"), str(work / "pcvr.zip"), str(work)]
    if inside_root:
        command = [str(ROOT / "tools/portable_root.sh"), "run", str(PORTABLE_ROOT), *command]
    run = subprocess.run(command, env=environment, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-4000:]
    assert "rendered" in run.stdout


@pytest.fixture
def renders(tmp_path):
    """Both runs' output folders: (here, in the root)."""
    if not archive().is_file():
        pytest.skip(f"{archive().relative_to(ROOT)} is not built: run `make extension`")
    if bpy.app.version_string.split()[0] != root_bpy_version():
        pytest.skip(f"bpy {bpy.app.version_string} here, {root_bpy_version()} in the root: run with .venv-bpy53")
    here = tmp_path / "here"
    inside = Path("/tmp") / f"pcvr-portable-{os.getpid()}"  # the root's /tmp
    prepare(here)
    prepare(PORTABLE_ROOT / inside.relative_to("/"))
    try:
        render(sys.executable, here)
        render("/opt/venv/bin/python", inside, inside_root=True)
        yield here / "out", PORTABLE_ROOT / inside.relative_to("/") / "out"
    finally:
        shutil.rmtree(PORTABLE_ROOT / inside.relative_to("/"), ignore_errors=True)


def test_the_root_lacks_the_build_machines_libraries():
    found = [path for name in BUILD_MACHINE_LIBRARIES
             for path in PORTABLE_ROOT.glob(f"usr/lib/**/{name}*.so*")]
    assert not found
    assert not (PORTABLE_ROOT / "usr/lib/x86_64-linux-gnu/libstdc++.so.6").resolve().samefile(
        Path("/usr/lib/x86_64-linux-gnu/libstdc++.so.6").resolve())


def test_renders_match_the_build_machine(renders):
    here, inside = renders
    # The module found every library, those it vendors in its own folder, the rest in the root's system.
    ldd = (inside / "ldd.txt").read_text()
    assert "not found" not in ldd, ldd
    for name in BUILD_MACHINE_LIBRARIES:
        [line] = [line for line in ldd.splitlines() if line.strip().startswith(name)]
        assert "/pcvr_native.libs/" in line, line

    ours, theirs = np.load(here / "images.npz"), np.load(inside / "images.npz")
    assert sorted(ours) == sorted(theirs) == ["cli_shaded", "cli_xray", "f12_shaded", "f12_xray"]
    for name in ours:
        image, other = ours[name], theirs[name]
        assert image.shape == other.shape, name
        assert image.max() > 0.1, f"{name} shows nothing: the scene is wrong"
        difference = np.abs(image - other).max() / np.abs(image).max()
        per_channel = np.abs(image - other).reshape(-1, image.shape[-1] if image.ndim == 3 else 1).max(axis=0)
        print(f"{name}: {image.shape}, largest difference {difference:.2e} of the maximum, per channel {per_channel}")
        assert difference <= TOLERANCE, f"{name}: differs by {difference:.2e} of its maximum"
