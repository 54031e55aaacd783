"""python -m pcvr_addon render: .vdb and .blend inputs to .exr, .png and .tif."""

import os
import subprocess
import sys
from pathlib import Path

import bpy
import numpy as np
import pcvr_native as pn
import pytest

import blender_scenes as bs
import clip_scenes as cs
import lit_scenes as ls
from pcvr_addon.cli import command_scene
from pcvr_addon.io import image_io

ROOT = Path(__file__).resolve().parents[2]


def pcvr(*args):
    run = subprocess.run([sys.executable, "-m", "pcvr_addon", "render", *map(str, args)],
                         cwd=ROOT, capture_output=True, text=True, timeout=120)
    return run


def check(run):
    assert run.returncode == 0, run.stdout + run.stderr


@pytest.fixture
def box_vdb(tmp_path):
    return bs.write_vdb(tmp_path / "box.vdb", bs.box())


def test_vdb_to_exr_and_png(tmp_path, box_vdb):
    check(pcvr(box_vdb, "-o", tmp_path / "box.exr", "--magnification", 2, "--method", "regular", "--gain", 2))
    exr = image_io.read_passes(str(tmp_path / "box.exr"))[""]
    assert exr.shape == (24, 24, 5)  # R, G, B, A, XRay; 8 voxels + 2 * 2 of room, 2 pixels each
    integral = exr[:, :, 4]
    # Density 1 through 8 voxels of 0.1: 0.8 in the middle.
    assert integral[12, 12] == pytest.approx(0.8, rel=1e-2)
    # The compensated passband dips below zero beside the edges: a negative integral shows 0 (issue 41).
    np.testing.assert_allclose(exr[:, :, 0], 1 - np.exp(-2 * np.maximum(integral, 0)), atol=1e-6)

    check(pcvr(box_vdb, "-o", tmp_path / "box.png", "--magnification", 2, "--method", "regular", "--gain", 2))
    png = image_io.read_passes(str(tmp_path / "box.png"))[""]
    assert png.shape == (24, 24, 4)
    np.testing.assert_allclose(png[:, :, :3], image_io.srgb_encode(exr[:, :, :3]), atol=0.6 / 255)
    assert not [name for name in os.listdir(tmp_path) if name.startswith(".")], "a temporary file was left"


def test_blend_with_its_own_camera(tmp_path, rng):
    bs.setup(64, 64)
    camera = bs.add_camera(location=(0.2, -3.0, 1.0), rotation=(1.25, 0.0, 0.05), lens=35.0)
    obj = bs.add_volume("Blob", bs.write_vdb(tmp_path / "blob.vdb", bs.blob(rng)), rotation=(0.3, 0.1, 0.0))
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"), copy=True)
    reference = bs.exact(bs.world_grid(obj), bs.reference_camera(width=40, height=30))

    check(pcvr(tmp_path / "scene.blend", "-o", tmp_path / "scene.exr", "--method", "regular",
               "--resolution", "40x30"))
    bs.assert_matches(image_io.read_passes(str(tmp_path / "scene.exr"))[""][:, :, 4], reference)

    check(pcvr(tmp_path / "scene.blend", "-o", tmp_path / "scene.tif", "--resolution", "40x30"))
    assert image_io.read_passes(str(tmp_path / "scene.tif"))[""].shape == (30, 40, 4)
    assert camera.name == "Camera"


def test_bad_arguments(tmp_path, box_vdb):
    run = pcvr(tmp_path / "nothing.vdb", "-o", tmp_path / "out.exr")
    assert run.returncode == 2 and "does not exist" in run.stderr
    run = pcvr(box_vdb, "-o", tmp_path / "out.exr", "--resolution", "40x30")
    assert run.returncode == 2 and "--magnification" in run.stderr
    run = pcvr(box_vdb, "-o", tmp_path / "out.jpg")
    assert run.returncode == 2 and not (tmp_path / "out.jpg").exists()


def test_numbered_vdb_is_a_sequence(tmp_path):
    for number, density in ((10, 1.0), (11, 3.0), (12, 2.0)):
        bs.write_vdb(tmp_path / f"fire_{number:04d}.vdb", bs.box(density=density))
    for args, density in (((), 1.0), (("--frame", 11), 3.0)):
        check(pcvr(tmp_path / "fire_0010.vdb", "-o", tmp_path / "fire.exr", "--magnification", 2,
                   "--method", "regular", *args))
        integral = image_io.read_passes(str(tmp_path / "fire.exr"))[""][:, :, 4]
        assert integral[12, 12] == pytest.approx(0.8 * density, rel=1e-2)


def test_without_openimageio(tmp_path, box_vdb):
    """bpy 4.2 bundles no OpenImageIO module: the command line says what to install, before rendering."""
    script = "import sys; sys.modules['OpenImageIO'] = None; from pcvr_addon.cli.main import main; sys.exit(main())"
    run = subprocess.run([sys.executable, "-c", script, "render", box_vdb, "-o", tmp_path / "box.exr"],
                         cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert run.returncode == 1 and "pip install openimageio" in run.stderr, run.stdout + run.stderr
    assert "Rendering" not in run.stdout and not (tmp_path / "box.exr").exists()


def test_shaded_vdb_with_a_preset_and_a_sun(tmp_path):
    head = ls.head_vdb(tmp_path / "head.vdb")
    lit = {}
    for side, direction in (("left", (1, 0, -1)), ("right", (-1, 0, -1))):  # light travelling right, then left
        check(pcvr(head, "-o", tmp_path / f"{side}.exr", "--mode", "shaded", "--preset", "ct-bone",
                   "--light-direction", *direction, "--magnification", 1))
        lit[side] = image_io.read_passes(str(tmp_path / f"{side}.exr"))[""]
    image = lit["left"]
    assert image.shape[2] == 6  # R, G, B, A, Z (the Depth pass), XRay
    alpha, depth = image[..., 3], image[..., 4]
    # The film is opaque: the world's grey shows where the head is not, at the background depth.
    assert (alpha == 1).all() and (depth[image[..., 5] == 0] == 1e10).all()
    # The head is lit from the side the light comes from: its left half is the brighter one, then its right
    # (measured: 1.50 times as bright, background included).
    half = image.shape[1] // 2
    brightness = {side: (pixels[:, :half, :3].sum(), pixels[:, half:, :3].sum()) for side, pixels in lit.items()}
    assert brightness["left"][0] > 1.3 * brightness["left"][1]
    assert brightness["right"][1] > 1.3 * brightness["right"][0]


def test_mip_png(tmp_path):
    check(pcvr(ls.head_vdb(tmp_path / "head.vdb"), "-o", tmp_path / "head.png", "--mode", "mip",
               "--preset", "CT MIP", "--magnification", 1, "--post-filter", "catmull_rom"))
    image = image_io.read_passes(str(tmp_path / "head.png"))[""]
    # White where bone is, the world's grey (0.05, sRGB-encoded) around the head.
    assert image[..., :3].max() > 0.9
    np.testing.assert_allclose(image[0, 0, :3], image_io.srgb_encode(0.05), atol=1 / 255)


def test_shaded_arguments(tmp_path, box_vdb):
    run = pcvr(box_vdb, "-o", tmp_path / "out.exr", "--mode", "shaded", "--preset", "CT Teeth")
    assert run.returncode == 2 and "no transfer-function preset 'CT Teeth'; there are: " in run.stderr
    run = pcvr(box_vdb, "-o", tmp_path / "out.exr", "--light-direction", 0, 0, 0)
    assert run.returncode == 2 and "needs a direction" in run.stderr
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"), copy=True)
    run = pcvr(tmp_path / "scene.blend", "-o", tmp_path / "out.exr", "--light-direction", 0, 0, -1)
    assert run.returncode == 2 and "--light-direction" in run.stderr


def test_sheet_fill_splat_and_sample_render_the_same_head(tmp_path):
    """--sheet-fill: the sheets splatted or sampled from the volume (at this magnification the automatic choice
    samples): the same head to within the reconstructions' difference (measured: 0.0057 on average over linear
    RGBA, 0.12 at most, at the skull's rim)."""
    head = ls.head_vdb(tmp_path / "head.vdb")
    images = {}
    for fill in ("splat", "sample", "auto"):
        check(pcvr(head, "-o", tmp_path / f"{fill}.exr", "--mode", "shaded", "--preset", "ct-bone", "--magnification", 1,
                   "--sheet-fill", fill))
        images[fill] = image_io.read_passes(str(tmp_path / f"{fill}.exr"))[""][..., :4]
    difference = np.abs(images["splat"] - images["sample"])
    assert difference.mean() <= 0.012 and difference.max() <= 0.25
    assert np.array_equal(images["auto"], images["sample"])
    run = pcvr(head, "-o", tmp_path / "out.exr", "--mode", "shaded", "--sheet-fill", "gather")
    assert run.returncode == 2 and "--sheet-fill" in run.stderr


def test_stream_above_reads_a_big_vdb_from_its_file(tmp_path):
    """--stream-above: a volume of more MiB is streamed (the status line says so), with the same image."""
    i = np.indices((96, 96, 96), dtype=np.float32) / 95 * 2 - 1
    filepath = bs.write_vdb(tmp_path / "field.vdb", np.exp(-3 * (i ** 2).sum(axis=0)).astype(np.float32))
    streamed = pcvr(filepath, "-o", tmp_path / "streamed.exr", "--magnification", 1, "--stream-above", 1)
    whole = pcvr(filepath, "-o", tmp_path / "whole.exr", "--magnification", 1, "--stream-above", 4)
    check(streamed)
    check(whole)
    assert "Streamed 1 volume from its file in 1 batch" in streamed.stdout
    assert "Streamed" not in whole.stdout and "pcvr: Voxels 884,736" in whole.stdout
    integral = {name: image_io.read_passes(str(tmp_path / f"{name}.exr"))[""][:, :, 4] for name in ("streamed", "whole")}
    np.testing.assert_allclose(integral["streamed"], integral["whole"], rtol=0, atol=1e-6 * integral["whole"].max())


def test_views_and_a_drr_from_hounsfield_units(tmp_path):
    """--view front looks along +Y with Z up (Blender's numpad 1), --view-direction along any vector, and
    --hounsfield integrates mu = MU_WATER (1 + HU / 1000) per centimetre of the scene's unit (metres here)."""
    values = np.full((16, 16, 16), -1000.0, np.float32)   # air
    values[4:12, 4:12, 2:6] = 1000.0                      # a slab of bone at the bottom (low k: low z)
    values[4:12, 4:12, 6:14] = 0.0                        # water above it
    ct = tmp_path / "ct.vdb"
    pn.Grid.from_dense(values, bs.centred(), background=-1000.0).write_vdb(str(ct))
    # The paper's passband: the rows read below count on its kernels' reach (the compensation reaches a node
    # further, and overshoots the bone's edge by up to 10%, as sharpening does at a step).
    check(pcvr(ct, "-o", tmp_path / "front.exr", "--magnification", 2, "--view", "front", "--hounsfield",
               "--passband", "paper"))
    front = image_io.read_passes(str(tmp_path / "front.exr"))[""][:, :, 4]
    # From the front Z is up: bone (mu 2 x 19.3 per metre) at the bottom, 0.8 m of it along the view at
    # voxels of 0.1 m, and water (19.3 per metre) above it.
    column = front[:, front.shape[1] // 2]
    first, last = np.flatnonzero(column > 1e-3 * column.max())[[0, -1]]  # rows from the top, 2 pixels a voxel
    water, bone = column[first + 4 + 8], column[last - 4 - 4]  # past the kernels' reach, mid-way through each
    assert water == pytest.approx(19.3 * 0.8, rel=0.03) and bone == pytest.approx(2 * 19.3 * 0.8, rel=0.03)
    check(pcvr(ct, "-o", tmp_path / "top.exr", "--magnification", 2, "--hounsfield", "0.2"))
    above = image_io.read_passes(str(tmp_path / "top.exr"))[""][:, :, 4]
    # From above: 0.4 m of bone and 0.8 m of water, at 20 per metre.
    assert above[above.shape[0] // 2, above.shape[1] // 2] == pytest.approx(20 * (2 * 0.4 + 0.8), rel=0.03)
    check(pcvr(ct, "-o", tmp_path / "along.exr", "--magnification", 2, "--view-direction", 0, 1, 0,
               "--hounsfield", "--passband", "paper"))
    np.testing.assert_array_equal(image_io.read_passes(str(tmp_path / "along.exr"))[""][:, :, 4], front)
    run = pcvr(ct, "-o", tmp_path / "x.exr", "--view", "front", "--view-direction", 0, 1, 0)
    assert run.returncode == 2 and "give one" in run.stderr
    check(pcvr(ct, "-o", tmp_path / "auto.exr", "--magnification", 2, "--hounsfield", "--gain", "auto"))
    auto = image_io.read_passes(str(tmp_path / "auto.exr"))[""]
    assert np.percentile(auto[:, :, 0][auto[:, :, 4] > 0], 99) == pytest.approx(0.8, abs=0.01)  # passes.EXPOSURE_GREY
    run = pcvr(ct, "-o", tmp_path / "x.exr", "--gain", "bright")
    assert run.returncode == 2 and "'bright' is not a number or 'auto'" in run.stderr


def test_clip_box_and_clip_planes_cut_every_volume(tmp_path, box_vdb):
    box, planes = ((0.5, 0.0, 0.0), (0.5, 1.0, 1.0)), [(0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.1)]
    check(pcvr(box_vdb, "-o", tmp_path / "cut.exr", "--magnification", 2, "--method", "regular",
               "--clip-box", *box[0], *box[1], *[value for plane in planes for value in ("--clip-plane", *plane)]))
    cut = image_io.read_passes(str(tmp_path / "cut.exr"))[""][:, :, 4]
    # The same scene here, as the command line makes it: the same camera and grid, cut by pcvr_native directly.
    obj = command_scene.vdb_scene(bpy.context.scene, box_vdb, magnification=2)
    grid, camera = bs.world_grid(obj), bs.reference_camera()
    reference = pn.render_xray(grid, camera, method="regular", clip_box=cs.world_to_box(*box), clip_planes=planes)
    bs.assert_matches(cut, reference, 1e-5)  # the same native call: only the threads' order of sums differs
    # x >= 0 and y >= 0 keep a quarter of the box's columns, z >= -0.1 five eighths of each.
    assert cut.sum() / pn.render_xray(grid, camera, method="regular").sum() == pytest.approx(0.25 * 5 / 8, rel=0.1)


def test_clip_box_of_a_blend_cuts_volumes_with_crops_of_their_own(tmp_path, box_vdb):
    bs.setup(32, 32)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=2.0)
    obj = bs.add_volume("Box", box_vdb)
    cs.crop(obj, cs.add_empty("Own Crop", location=(0.0, 0.2, 0.0), rotation=(0.0, 0.0, 0.4), scale=(0.5,) * 3))
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"), copy=True)
    check(pcvr(tmp_path / "scene.blend", "-o", tmp_path / "cut.exr", "--method", "regular",
               "--clip-box", 0.2, 0, 0, 0.3, 0.3, 1))
    # The command line's box is cut by planes on its faces: x in [-0.1, 0.5], y in [-0.3, 0.3], z in [-1, 1].
    faces = [(1, 0, 0, 0.1), (-1, 0, 0, 0.5), (0, 1, 0, 0.3), (0, -1, 0, 0.3), (0, 0, 1, 1), (0, 0, -1, 1)]
    reference = pn.render_xray(bs.world_grid(obj), bs.reference_camera(), method="regular", clip_planes=faces,
                               clip_box=cs.world_to_box((0.0, 0.2, 0.0), (0.5,) * 3, 0.4), passband="paper")  # the scene's
    bs.assert_matches(image_io.read_passes(str(tmp_path / "cut.exr"))[""][:, :, 4], reference, 1e-5)


@pytest.mark.parametrize("argv, message", [
    (["--clip-box", 0, 0, 0, 1, 1, 0], "the half-sizes must be positive"),
    (["--clip-plane", 0, 0, 0, 1], "--clip-plane needs a normal"),
])
def test_clipping_mistakes(tmp_path, box_vdb, argv, message):
    run = pcvr(box_vdb, "-o", tmp_path / "out.exr", *argv)
    assert run.returncode == 2 and message in run.stderr and not (tmp_path / "out.exr").exists()


def test_shadows_darken_a_head_lit_from_the_side(tmp_path):
    """--shadows: the skull shadows the light on its way through the head (measured: the image 0.80 times as
    bright); --no-shadows and no option leave it as it was."""
    head = ls.head_vdb(tmp_path / "head.vdb")
    images = {}
    for name, option in (("default", ()), ("on", ("--shadows",)), ("off", ("--no-shadows",))):
        check(pcvr(head, "-o", tmp_path / f"{name}.exr", "--mode", "shaded", "--preset", "ct-bone",
                   "--light-direction", 1, 0, -0.3, "--magnification", 1, *option))
        images[name] = image_io.read_passes(str(tmp_path / f"{name}.exr"))[""][..., :3]
    assert np.array_equal(images["default"], images["off"])
    assert images["on"].sum() < 0.88 * images["off"].sum()
