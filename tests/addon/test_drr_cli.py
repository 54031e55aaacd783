"""python -m pcvr_addon render --cone-beam: C-arm DRRs of a .vdb and of a CT series, one view and a gantry sweep,
as line integrals and as I0 exp(-line integral), equal to pn.render_xray through pn.cameras.cone_beam."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pcvr_native as pn
import pytest
from pcvr_native.cameras import cone_beam

import blender_scenes as bs
import scan_files as sf
from pcvr_addon.cli import main as cli_main
from pcvr_addon.io import image_io

ROOT = Path(__file__).resolve().parents[2]
# The scene's camera matrices are single precision: measured 8e-5 of the peak apart (tests/addon/test_c_arm_view.py).
TOLERANCE = 1e-3


def pcvr(tmp_path, *args):
    env = dict(os.environ, XDG_CACHE_HOME=str(tmp_path / "cache"))  # a scan's .vdb cached in the test's folder
    run = subprocess.run([sys.executable, "-m", "pcvr_addon", "render", *map(str, args)], cwd=ROOT,
                         capture_output=True, text=True, timeout=300, env=env)
    assert run.returncode == 0, run.stdout + run.stderr
    return run


def read_channel(path):
    oiio = image_io.openimageio()
    image = oiio.ImageInput.open(str(path))
    try:
        spec = image.spec()
        return np.asarray(image.read_image(spec.format)).reshape(spec.height, spec.width), str(spec.format)
    finally:
        image.close()


def centre(grid):
    lo, hi = np.asarray(grid.index_bbox, dtype=np.float64)
    return (grid.index_to_world @ np.append((lo + hi) / 2, 1.0))[:3]


def test_vdb_to_float_tiff_of_line_integrals(tmp_path, rng):
    # 2 mm voxels; the .vdb's world units are taken as millimetres.
    path = bs.write_vdb(tmp_path / "blob.vdb", bs.blob(rng), bs.centred(2.0))
    pcvr(tmp_path, path, "-o", tmp_path / "drr.tif", "--cone-beam", 300, 500, "--detector", "40x32",
         "--pixel-spacing", 1.5, 1.2, "--gantry", 60, "--tilt", -15, "--isocentre", 2, -1, 3,
         "--detector-offset", 5, 2)
    image, pixel_type = read_channel(tmp_path / "drr.tif")
    assert pixel_type == "float" and image.shape == (32, 40)
    expected = pn.render_xray(pn.read_vdb(path), cone_beam(300, 500, (40, 32), (1.5, 1.2), (2, -1, 3), 60, -15, (5, 2)))
    bs.assert_matches(image, expected, TOLERANCE)


def test_ct_series_gantry_sweep_as_16_bit_intensities(tmp_path, rng):
    # A CT series (Hounsfield units, LPS millimetres): a water ball with a bone marker, swept by the gantry.
    n = 24
    i = np.indices((n, n, n)) - (n - 1) / 2
    hu = np.where((i ** 2).sum(axis=0) < (n / 2.5) ** 2, 0.0, -1000.0)
    hu[(i[0] - 4) ** 2 + (i[1] + 3) ** 2 + (i[2] - 5) ** 2 < 6] = 1000.0
    sf.dicom_series(str(tmp_path / "ct"), (hu + 1024).astype(np.int16), origin=(-20.0, 10.0, -30.0),
                    pixel_spacing=(1.5, 1.5), step=(0.0, 0.0, 2.0), intercept=-1024.0)
    run = pcvr(tmp_path, tmp_path / "ct", "-o", tmp_path / "drr_##.png", "--cone-beam", 500, 800,
               "--detector", "48x48", "--pixel-spacing", 1.6, 1.6, "--angles", "0:360:90", "--intensity", 40000)
    assert "4 rendered" in run.stderr and "DRRs per second" in run.stderr
    manifest = json.loads((tmp_path / "drr.manifest.json").read_text())
    assert manifest["images_per_second"] > 0

    grid = pn.read_vdb(manifest["jobs"][0]["input"])  # the scan's cached .vdb: HU in LPS millimetres
    mu = pn.AttenuationMap.hounsfield(0.193 / 10)  # per millimetre, the default MU_WATER per centimetre
    for index, gantry in enumerate((0, 90, 180, 270)):
        image, pixel_type = read_channel(tmp_path / f"drr_{index:02d}.png")
        assert pixel_type == "uint16"
        integral = pn.render_xray(grid, cone_beam(500, 800, (48, 48), (1.6, 1.6), centre(grid), gantry),
                                  attenuation=mu)
        expected = np.clip(np.rint(40000 * np.exp(-integral)), 0, 65535)
        # I0 exp(-L) moves by about I0 dL: the line integrals' tolerance times their peak, in counts.
        assert np.abs(image - expected).max() <= 40000 * TOLERANCE * integral.max() + 1
        assert image.min() < 0.6 * 40000  # about 30 mm of water and the bone marker absorb
    # Gantry 0 and 180 see the ball from opposite sides: mirror images (up to the marker's magnification).
    front, back = (read_channel(tmp_path / f"drr_{index:02d}.png")[0].astype(float) for index in (0, 2))
    assert np.abs(front - back[:, ::-1]).mean() < 0.05 * front.mean()


@pytest.mark.parametrize("arguments, message", [
    (["--detector", "64x64"], "--detector needs --cone-beam"),
    (["--cone-beam", "800", "500"], "must exceed SAD"),
    (["--cone-beam", "500", "800", "--view", "front"], "--view frames an orthographic camera"),
    (["--cone-beam", "500", "800", "--pixel-spacing", "1", "0"], "--pixel-spacing must be positive"),
    (["--cone-beam", "500", "800", "--mode", "shaded"], "X-ray mode only"),
])
def test_bad_c_arm_options_are_refused(tmp_path, capsys, arguments, message):
    path = bs.write_vdb(tmp_path / "box.vdb", bs.box())
    with pytest.raises(SystemExit):
        cli_main.main(["render", path, "-o", str(tmp_path / "drr.exr"), *arguments])
    assert message in capsys.readouterr().err


def test_line_integrals_need_a_float_format_and_a_sweep_owns_the_gantry(tmp_path, capsys):
    path = bs.write_vdb(tmp_path / "box.vdb", bs.box())
    with pytest.raises(SystemExit):
        cli_main.main(["render", path, "-o", str(tmp_path / "drr.png"), "--cone-beam", "500", "800"])
    assert "need a float image" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli_main.main(["render", path, "-o", str(tmp_path / "drr_#.exr"), "--cone-beam", "500", "800",
                       "--angles", "0:90:45", "--gantry", "10"])
    assert "no --gantry with it" in capsys.readouterr().err
