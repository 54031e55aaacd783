#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later

"""Package the PCVR add-on as a Blender extension (`make extension`).

Stages pcvr_addon/*, blender_manifest.toml, the native wheels from dist/ (one per Python that Blender
ships) and the pure-Python wheels that extension_requirements.txt pins into build/extension/pcvr, then
runs Blender's own extension tool on it: `build --split-platforms` into dist/, then `validate` on the
archive. Prints the path of the archive.

Blender installs, of the manifest's `wheels`, those that fit its platform and Python, so one archive
serves Blender 4.2 to 5.0 (Python 3.11) and 5.1 to 5.3 (Python 3.13).
"""

import argparse
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
MANIFEST = ROOT / "blender_manifest.toml"
ADDON = ROOT / "pcvr_addon"
REQUIREMENTS = ROOT / "extension_requirements.txt"


def find_blender_ext():
    """Blender's extension command line tool, from the bpy package of this interpreter."""
    import importlib.util
    spec = importlib.util.find_spec("bpy")
    if spec is None or spec.origin is None:
        sys.exit("build_extension: bpy is not installed in this Python; run `make setup` first")
    found = sorted(Path(spec.origin).parent.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
    if not found:
        sys.exit(f"build_extension: blender_ext.py not found under {Path(spec.origin).parent}")
    return found[-1]


def native_wheels(dist):
    wheels = sorted(dist.glob("pcvr_native-*.whl"))
    if not wheels:
        sys.exit(f"build_extension: no pcvr_native wheel in {dist}; run `make native` first")
    return wheels


def check_manifest(wheels):
    """The manifest must name exactly the native wheels the build produced."""
    with open(MANIFEST, "rb") as fh:
        manifest = tomllib.load(fh)
    expected = [f"./wheels/{wheel.name}" for wheel in wheels]
    if sorted(manifest.get("wheels", [])) != expected:
        sys.exit(f"build_extension: {MANIFEST.name} lists wheels = {manifest.get('wheels')}, but the build "
                 f"produced {[wheel.name for wheel in wheels]}; set wheels = {expected}")
    return manifest


def requirements(path=REQUIREMENTS):
    """The `name==version` lines of extension_requirements.txt (comments and blank lines skipped)."""
    pins = []
    for number, line in enumerate(path.read_text().splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9._-]*==[A-Za-z0-9.!+_-]+", line):
            sys.exit(f"build_extension: {path.name}, line {number}: {line!r} is not `name==version`")
        pins.append(line)
    return pins


def download_pure_wheels(pins, folder):
    """Each pinned package as its py3-none-any wheel, without its dependencies (they are pinned too):
    the same file serves every Python and platform Blender runs on."""
    if not pins:
        return []
    run([sys.executable, "-m", "pip", "download", "-q", "--only-binary=:all:", "--no-deps",
         "--platform", "any", "--abi", "none", "--python-version", "3.11",  # Blender 4.2's Python, the oldest
         "--dest", folder, *pins])
    wheels = sorted(folder.glob("*.whl"))
    impure = [wheel.name for wheel in wheels if not wheel.name.endswith("-none-any.whl")]
    if impure:
        sys.exit(f"build_extension: the requirements must pin pure-Python packages; these wheels are "
                 f"built for one Python or platform: {impure}")
    return wheels


def with_wheels(manifest_text, wheel_names):
    """The manifest's text with its `wheels = [...]` list replaced (a TOML array may span lines)."""
    listed = ",\n".join(f'  "./wheels/{name}"' for name in wheel_names)
    text, count = re.subn(r"^wheels\s*=\s*\[[^\]]*\]", f"wheels = [\n{listed},\n]", manifest_text, flags=re.M)
    if count != 1:
        sys.exit(f"build_extension: {MANIFEST.name} has no `wheels = [...]` list to extend")
    return text


def stage(staging, native, pins):
    """The extension's folder: the add-on, the native wheels and the pinned ones, and a manifest that lists
    them all."""
    if staging.exists():
        shutil.rmtree(staging)
    shutil.copytree(ADDON, staging, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    wheel_folder = staging / "wheels"
    wheel_folder.mkdir()
    pure = download_pure_wheels(pins, wheel_folder)  # first: it checks every wheel in the folder
    for wheel in native:
        shutil.copy2(wheel, wheel_folder / wheel.name)
    names = [wheel.name for wheel in native] + [wheel.name for wheel in pure]
    (staging / MANIFEST.name).write_text(with_wheels(MANIFEST.read_text(), names))


def archives(manifest, dist):
    """The archives `build --split-platforms` writes: <id>-<version>-<platform>.zip."""
    return [dist / f"{manifest['id']}-{manifest['version']}-{platform.replace('-', '_')}.zip"
            for platform in manifest["platforms"]]


def run(command):
    print("+", " ".join(str(part) for part in command), flush=True)
    subprocess.run([str(part) for part in command], check=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dist", type=Path, default=ROOT / "dist",
                        help="where the wheel is and the archive goes (default: dist/)")
    parser.add_argument("--staging", type=Path, default=ROOT / "build" / "extension" / "pcvr",
                        help="staging folder (default: build/extension/pcvr)")
    parser.add_argument("--requirements", type=Path, default=REQUIREMENTS,
                        help="the pure-Python wheels to ship (default: extension_requirements.txt)")
    args = parser.parse_args()

    native = native_wheels(args.dist)
    manifest = check_manifest(native)
    stage(args.staging, native, requirements(args.requirements))

    blender_ext = find_blender_ext()
    for archive in archives(manifest, args.dist):
        archive.unlink(missing_ok=True)  # never validate a stale one
    run([sys.executable, blender_ext, "build", "--split-platforms",
         "--source-dir", args.staging, "--output-dir", args.dist])
    for archive in archives(manifest, args.dist):
        if not archive.is_file():
            sys.exit(f"build_extension: Blender's tool did not write {archive}")
        run([sys.executable, blender_ext, "validate", archive])
        print(archive)


if __name__ == "__main__":
    main()
