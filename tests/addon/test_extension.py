"""The packaged extension (dist/pcvr-*.zip, built by `make extension`) installs, enables and renders."""

import os
import subprocess
import sys
import tomllib
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
