"""Scale: voxels from 1e-12 to 1e9 world units, and volumes 1e8 units from the origin, render the
unit-scale image times the scale (a line integral is density times world length).

Measured (48 x 48, a 12^3 volume, every method): at the origin the scaled image matches the unit one
to 1.9e-7 of its peak (float32 rounding; 8.4e-7 in perspective, whose footprints are modelled in float); 1e8 units out, positions are resolved only to
|offset| x 2.2e-16, and the error is at most half that resolution measured in voxels (1.2e-5 for
1.7e-4-unit voxels). Where the resolution passes a tenth of a voxel the grid is refused with the
numbers. Files carry scales OpenVDB's transform cannot hold in metadata."""

import struct

import numpy as np
import pytest

import pcvr_native as pn
from pcvr_native import phantoms

from _io_helpers import HAVE_BPY, run_blender_openvdb, run_python
from stress_helpers import METHODS, max_error, placed, resolution_in_voxels, scene_camera

PHANTOM = phantoms.dense_volume(12, seed=3)
VOXEL = float(np.linalg.norm(PHANTOM.index_to_world[:3, 0]))
FLOAT32_ROUNDING = 4e-7  # twice the largest error measured at the origin, orthographic
# Perspective footprints come from a per-block model evaluated in float (docs/how-it-works.md,
# *Perspective*), whose coefficients round differently at each scale: up to 8.4e-7 measured.
FLOAT32_ROUNDING_PERSPECTIVE = 1.7e-6


@pytest.fixture(scope="module")
def unit_images():
    grid = PHANTOM.grid()
    return {(method, persp): pn.render_xray(grid, scene_camera(1.0, 0.0, persp), method=method)
            for method in METHODS for persp in (False, True)}


@pytest.mark.parametrize("persp", [False, True], ids=["ortho", "persp"])
@pytest.mark.parametrize("scale,offset", [
    (1e-12, 0.0), (1e-9, 0.0), (1e-6, 0.0), (1e-3, 0.0), (1e3, 0.0), (1e6, 0.0), (1e9, 0.0),
    (1e-5, 1e8), (1e-3, 1e8), (1.0, 1e8), (1e6, 1e8),
])
def test_scaled_scene_renders_the_unit_image(unit_images, scale, offset, persp):
    where = np.array([1.0, -0.5, 0.25]) * offset
    grid = PHANTOM.grid().with_index_to_world(placed(scale, where) @ PHANTOM.index_to_world)
    cam = scene_camera(scale, where, persp)
    tolerance = (FLOAT32_ROUNDING_PERSPECTIVE if persp else FLOAT32_ROUNDING) + resolution_in_voxels(where, scale * VOXEL)
    for method in METHODS:
        image = pn.render_xray(grid, cam, method=method)
        assert np.isfinite(image).all()
        error = max_error(image / scale, unit_images[method, persp])
        assert error <= tolerance, f"{method}: error {error:.2e} > {tolerance:.2e}"


@pytest.mark.parametrize("scale", [1e-6, 1e-9])
def test_unresolvable_position_is_refused_with_the_numbers(scale):
    with pytest.raises(pn.GridError) as info:
        PHANTOM.grid().with_index_to_world(placed(scale, (1e8, 0.0, 0.0)) @ PHANTOM.index_to_world)
    message = str(info.value)
    for words in ("from the origin", "double precision", "voxels", "move the volume"):
        assert words in message, message


@pytest.mark.parametrize("scale", [1e-12, 1e-9, 1e-6, 1e-5, 1e-4, 1.0, 1e9])
@pytest.mark.parametrize("compression", ["blosc", "none"])
def test_tiny_and_huge_voxels_survive_a_file(tmp_path, scale, compression):
    """from_dense keeps the matrix in double; write_vdb stores what OpenVDB's transform cannot hold
    (a determinant below 3e-15) as a power of ten in 'pcvr_world_scale' metadata; read_vdb applies it."""
    matrix = placed(scale, (3.0 * scale, -2.0 * scale, 0.5)) @ PHANTOM.index_to_world
    grid = pn.Grid.from_dense(PHANTOM.values, matrix)
    np.testing.assert_array_equal(grid.index_to_world, matrix)
    path = tmp_path / "tiny.vdb"
    grid.write_vdb(path, compression=compression)
    back = pn.read_vdb(path)
    # Dividing by the stored power of ten and multiplying back rounds each entry once or twice.
    np.testing.assert_allclose(back.index_to_world, matrix, rtol=1e-15, atol=1e-15 * np.abs(matrix).max())
    np.testing.assert_array_equal(back.to_dense(), grid.to_dense())


@pytest.mark.skipif(not HAVE_BPY, reason="needs Blender's OpenVDB")
def test_blender_reads_a_file_that_carries_its_scale_in_metadata(tmp_path):
    """Other readers see the stored transform (voxels near one unit) and the metadata."""
    path = tmp_path / "microscopy.vdb"
    pn.Grid.from_dense(PHANTOM.values, placed(1e-6, 0.0)).write_vdb(path)
    proc = run_blender_openvdb(f"""
        grids, meta = vdb.readAll({str(path)!r})
        g = grids[0]
        print('SCALE', g['pcvr_world_scale'], 'VOXEL', g.transform.voxelSize()[0])
    """)
    words = proc.stdout.split()
    assert float(words[words.index("SCALE") + 1]) == pytest.approx(1e-6)
    assert float(words[words.index("VOXEL") + 1]) == pytest.approx(1.0)


def _patched(path, old_values, new_values):
    """The file with every little-endian double in `old_values` replaced by its partner."""
    data = path.read_bytes()
    for old, new in zip(old_values, new_values):
        packed = struct.pack("<d", old)
        assert packed in data, old
        data = data.replace(packed, struct.pack("<d", new))
    path.write_bytes(data)


@pytest.mark.skipif(not HAVE_BPY, reason="needs Blender's OpenVDB")
def test_file_with_a_tiny_scale_map_reads(tmp_path):
    """OpenVDB reads a ScaleMap without checking it (only its AffineMap refuses small determinants):
    a file another writer gave 1e-6 voxels reads, without building the AffineMap that would refuse."""
    path = tmp_path / "scale_map.vdb"
    run_blender_openvdb(f"""
        g = vdb.FloatGrid(); g.name = 'density'
        g.copyFromArray(np.ones((4, 4, 4), np.float32))
        g.transform = vdb.createLinearTransform(voxelSize=0.375)
        vdb.write({str(path)!r}, [g])
    """)
    # Scale, voxel size, inverse scale, inverse square and inverse twice the scale.
    _patched(path, [0.375, 1 / 0.375, 1 / 0.375 ** 2, 0.5 / 0.375], [1e-6, 1e6, 1e12, 5e5])
    grid = pn.read_vdb(path)
    np.testing.assert_allclose(np.diag(grid.index_to_world)[:3], 1e-6)


@pytest.mark.skipif(not HAVE_BPY, reason="needs Blender's OpenVDB")
def test_file_with_a_tiny_affine_map_says_why_it_cannot_be_read(tmp_path):
    """OpenVDB itself refuses to load an AffineMap with a determinant below 3e-15 ("nearly singular
    matrix"): the error names the grid, the file, the voxel size and what to do."""
    path = tmp_path / "affine_map.vdb"
    linear = np.array([[0.625, 0.125, 0.0], [-0.125, 0.625, 0.0], [0.0, 0.0, 0.5625]])
    run_blender_openvdb(f"""
        g = vdb.FloatGrid(); g.name = 'cells'
        g.copyFromArray(np.ones((4, 4, 4), np.float32))
        m = np.eye(4); m[:3, :3] = np.array({linear.tolist()}).T
        g.transform = vdb.createLinearTransform(m.tolist())
        vdb.write({str(path)!r}, [g])
    """)
    _patched(path, [0.625, 0.125, -0.125, 0.5625], [0.625e-6, 0.125e-6, -0.125e-6, 0.5625e-6])
    proc = run_python(f"""
        import pcvr_native as pn
        try:
            pn.read_vdb({str(path)!r})
        except pn.GridError as e:
            print('GridError:', e)
    """)
    assert proc.returncode == 0, proc.stderr
    for words in ("'cells'", "affine_map.vdb", "voxels of about 6", "e-07 world units", "OpenVDB", "micrometres"):
        assert words in proc.stdout, proc.stdout
