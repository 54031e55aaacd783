"""Edge cases of the view, rendered by Blender's PCVR engine and held to pcvr_native's exact method:
a render border of one pixel, a camera inside a volume, voxels of a micrometre."""

import numpy as np
import pcvr_native as pn
import pytest

import blender_scenes as bs


@pytest.fixture
def blob_object(tmp_path, rng):
    return bs.add_volume("Blob", bs.write_vdb(tmp_path / "blob.vdb", bs.blob(rng)), rotation=(0.4, 0.2, 0.9))


@pytest.mark.parametrize("crop", [True, False], ids=["crop", "no_crop"])
def test_render_border_of_one_pixel(blob_object, crop):
    scene = bs.setup(80, 60)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=2.0)
    full = bs.exact(bs.world_grid(blob_object))
    render = scene.render
    render.use_border, render.use_crop_to_border = True, crop
    # Pixel (40, 28) from the bottom left, row 31 from the top: borders half a pixel either side,
    # which Blender truncates to it.
    render.border_min_x, render.border_max_x = 40.5 / 80, 41.5 / 80
    render.border_min_y, render.border_max_y = 28.5 / 60, 29.5 / 60
    image = bs.xray(bs.render(scene))
    expected = full[31:32, 40:41]
    assert expected.max() > 0
    if crop:
        assert image.shape == (1, 1)
        bs.assert_matches(image, expected)
    else:
        assert image.shape == full.shape
        bs.assert_matches(image[31:32, 40:41], expected)
        assert np.count_nonzero(image) == 1


def test_camera_inside_a_volume(tmp_path):
    """The eye in the middle of a constant block, its clip start a hundredth of a voxel away: voxels
    whose kernels reach behind the eye are integrated per ray (linearised, they gave 18 times
    exact's integral). Within 2% of the peak (tests/stress/test_camera.py measured 0.9%)."""
    scene = bs.setup(48, 48)
    obj = bs.add_volume("Block", bs.write_vdb(tmp_path / "block.vdb", np.ones((16, 16, 16), np.float32)))
    camera = bs.add_camera(location=(0.02, -0.03, 0.01), rotation=(1.2, 0.0, 0.4), lens=20.0)
    camera.data.clip_start = 0.001  # voxels are 0.1
    image = bs.xray(bs.render(scene))
    bs.assert_matches(image, bs.exact(bs.world_grid(obj)), tolerance=0.02)


def test_micrometre_voxels(tmp_path):
    """A volume written in metres with 1e-6 voxels (OpenVDB's transform cannot hold them: the file
    keeps them in 'pcvr_world_scale' metadata), framed by a camera 50 micrometres away."""
    scene = bs.setup(48, 48)
    path = tmp_path / "cells.vdb"
    pn.Grid.from_dense(bs.box(), bs.centred(voxel_size=1e-6)).write_vdb(str(path))
    obj = bs.add_volume("Cells", path)
    camera = bs.add_camera(location=(0.0, 0.0, 5e-5), ortho_scale=2.4e-5)
    camera.data.clip_start, camera.data.clip_end = 1e-6, 1e-3
    image = bs.xray(bs.render(scene))
    reference = bs.exact(bs.world_grid(obj))
    assert reference.max() == pytest.approx(8e-6, rel=0.02)  # density 1 through 8 voxels of 1e-6
    bs.assert_matches(image, reference)
