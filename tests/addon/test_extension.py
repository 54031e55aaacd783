"""The packaged extension (dist/pcvr-*.zip, built by `make extension`): its wheels, and that it installs, enables and
renders."""

import os
import re
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent


def archive():
    with open(ROOT / "blender_manifest.toml", "rb") as fh:
        manifest = tomllib.load(fh)
    return ROOT / "dist" / f"{manifest['id']}-{manifest['version']}-linux_x64.zip"


@pytest.mark.parametrize("ending", ["disabled", "left_enabled"])
def test_install_enable_and_render(tmp_path, ending):
    if not archive().is_file():
        pytest.skip(f"{archive().relative_to(ROOT)} is not built: run `make extension` (`make test` does)")
    environment = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "blender"),
                       PYTHONPATH=os.pathsep.join(filter(None, [str(HERE), str(ROOT), os.environ.get("PYTHONPATH")])))
    command = [sys.executable, str(HERE / "install_extension.py"), str(archive()), str(tmp_path)]
    if ending == "left_enabled":
        command.append("--leave-enabled")  # Blender disables it at exit (see compat.unregister_at_exit)
    run = subprocess.run(command, env=environment, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "installed, enabled and rendered" in run.stdout


# What the module and the libraries in its wheel may take from the system: glibc and GCC's runtime
# (auditwheel's manylinux policy), nothing that the build machine's packages provide.
SYSTEM_LIBRARIES = {"libc.so.6", "libm.so.6", "libdl.so.2", "librt.so.1", "libpthread.so.0",
                    "ld-linux-x86-64.so.2", "libstdc++.so.6", "libgcc_s.so.1", "libz.so.1"}


def needed_libraries(shared_object):
    """The DT_NEEDED entries of an ELF file (readelf, from binutils)."""
    dynamic = subprocess.run(["readelf", "-d", str(shared_object)], capture_output=True, text=True, check=True)
    return re.findall(r"\(NEEDED\)\s+Shared library: \[([^\]]+)\]", dynamic.stdout)


def test_the_archive_has_a_self_contained_wheel_for_each_python(tmp_path):
    if not archive().is_file():
        pytest.skip(f"{archive().relative_to(ROOT)} is not built: run `make extension`")
    with zipfile.ZipFile(archive()) as extension:
        manifest = tomllib.loads(extension.read("blender_manifest.toml").decode())
        listed = [name.removeprefix("./") for name in manifest["wheels"]]
        assert sorted(listed) == sorted(name for name in extension.namelist() if name.endswith(".whl"))
        native = [name for name in listed if Path(name).name.startswith("pcvr_native-")]
        # Blender 4.2 to 5.0 run Python 3.11, 5.1 to 5.3 Python 3.13.
        assert sorted(Path(name).name.split("-")[2] for name in native) == ["cp311", "cp313"]
        for name in native:
            extension.extract(name, tmp_path)
    for wheel in (tmp_path / "wheels").glob("pcvr_native-*.whl"):
        files = tmp_path / wheel.stem
        zipfile.ZipFile(wheel).extractall(files)
        vendored = {path.name for path in (files / "pcvr_native.libs").iterdir()}
        assert any(name.startswith("libopenvdb-") for name in vendored)  # renamed: never bpy's own
        for shared_object in [*files.glob("pcvr_native/_pcvr*.so"), *(files / "pcvr_native.libs").iterdir()]:
            outside = set(needed_libraries(shared_object)) - vendored - SYSTEM_LIBRARIES
            assert not outside, f"{wheel.name}: {shared_object.name} needs {sorted(outside)} from the system"


def test_extension_requirements(tmp_path):
    """extension_requirements.txt: `name==version` lines, each wheel listed in the staged manifest."""
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        import build_extension
    finally:
        sys.path.remove(str(ROOT / "tools"))
    build_extension.requirements()  # the checkout's own file reads
    pins = tmp_path / "requirements.txt"
    pins.write_text("# header\n\npydicom==3.0.1  # DICOM\nnibabel==5.3.2\n")
    assert build_extension.requirements(pins) == ["pydicom==3.0.1", "nibabel==5.3.2"]
    pins.write_text("pydicom==3.0.1\nnibabel>=5\n")
    with pytest.raises(SystemExit, match=r"line 2: 'nibabel>=5' is not `name==version`"):
        build_extension.requirements(pins)

    names = ["pcvr_native-0.1.0-cp311-cp311-manylinux_2_35_x86_64.whl", "pydicom-3.0.1-py3-none-any.whl"]
    staged = tomllib.loads(build_extension.with_wheels((ROOT / "blender_manifest.toml").read_text(), names))
    assert staged["wheels"] == [f"./wheels/{name}" for name in names]
    assert staged["id"] == "pcvr" and staged["permissions"]
