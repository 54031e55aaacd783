"""A volume that cannot be rendered is reported, naming object and file; the others still render."""

import shutil
from pathlib import Path

import bpy
import pytest

import blender_scenes as bs
from pcvr_addon.io import image_io


@pytest.fixture
def good(tmp_path, rng):
    bs.setup(48, 48)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=3.0)
    obj = bs.add_volume("Good", bs.write_vdb(tmp_path / "good.vdb", bs.blob(rng)), location=(-0.5, 0.0, 0.0))
    return bs.world_grid(obj)


# A real OpenVDB file with one Vec3S grid, 'velocity' (8^3 voxels of (1, 1, 1)), written by the openvdb
# module of Blender 5.0; bpy 4.2 has no openvdb module to write one with:
#     grid = openvdb.Vec3SGrid(); grid.name = "velocity"
#     grid.fill((0, 0, 0), (7, 7, 7), (1.0, 1.0, 1.0), True)
#     grid.transform = openvdb.createLinearTransform(voxelSize=0.1)
#     openvdb.write("velocity.vdb", grids=[grid])
VECTOR_GRID = Path(__file__).resolve().parent / "data" / "velocity.vdb"


def bad_volume(tmp_path, case):
    """A volume object named "Bad" at x = 0.5 whose file is `case`-broken; returns the file name."""
    filepath = tmp_path / f"{case}.vdb"
    grid = ""
    if case == "missing":
        pass
    elif case == "corrupt":
        filepath.write_bytes(b"this is not an OpenVDB file" * 100)
    elif case == "unknown_grid":
        bs.write_vdb(filepath, bs.box())
        grid = "temperature"
    elif case == "vector_grid":
        shutil.copyfile(VECTOR_GRID, filepath)
        grid = "velocity"
    obj = bs.add_volume("Bad", filepath, location=(0.5, 0.0, 0.0))
    obj.data.pcvr.grid = grid
    return filepath.name


@pytest.mark.parametrize("case", ["missing", "corrupt", "unknown_grid", "vector_grid"])
def test_error_is_reported_and_others_render(tmp_path, good, case):
    filename = bad_volume(tmp_path, case)
    with pytest.raises(RuntimeError, match=f"'Bad'.*{filename}"):
        bpy.ops.render.render(write_still=False)
    image = bs.xray(image_io.render_result_passes(bpy.context.scene))
    bs.assert_matches(image, bs.exact(good))
