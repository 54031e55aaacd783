#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later

"""Package the PCVR add-on as a Blender extension (`make extension`).

Stages pcvr_addon/*, blender_manifest.toml and the native wheel from dist/ into build/extension/pcvr,
then runs Blender's own extension tool on it: `build --split-platforms` into dist/, then `validate`
on the archive. Prints the path of the archive.
"""

import argparse
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
MANIFEST = ROOT / "blender_manifest.toml"
ADDON = ROOT / "pcvr_addon"


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


def find_wheel(dist):
    wheels = sorted(dist.glob("pcvr_native-*.whl"))
    if len(wheels) != 1:
        sys.exit(f"build_extension: expected one pcvr_native wheel in {dist}, found "
                 f"{[w.name for w in wheels] or 'none'}; run `make native` first")
    return wheels[0]


def check_manifest(wheel):
    """The manifest must name exactly the wheel the build produced."""
    with open(MANIFEST, "rb") as fh:
        manifest = tomllib.load(fh)
    expected = [f"./wheels/{wheel.name}"]
    if manifest.get("wheels") != expected:
        sys.exit(f"build_extension: {MANIFEST.name} lists wheels = {manifest.get('wheels')}, but the build "
                 f"produced {wheel.name}; set wheels = {expected}")
    return manifest


def stage(staging, wheel):
    if staging.exists():
        shutil.rmtree(staging)
    shutil.copytree(ADDON, staging, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    shutil.copy2(MANIFEST, staging / MANIFEST.name)
    (staging / "wheels").mkdir()
    shutil.copy2(wheel, staging / "wheels" / wheel.name)


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
    args = parser.parse_args()

    wheel = find_wheel(args.dist)
    manifest = check_manifest(wheel)
    stage(args.staging, wheel)

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
