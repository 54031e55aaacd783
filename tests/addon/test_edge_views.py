"""Edge cases of the view, rendered by Blender's PCVR engine and held to pcvr_native's exact method:
a camera inside a volume, voxels of a micrometre. (A render border of one pixel: test_render.py.)"""

import numpy as np
import pcvr_native as pn
import pytest

import blender_scenes as bs


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
