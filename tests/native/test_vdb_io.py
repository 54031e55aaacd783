"""Reading and writing OpenVDB files: round trips, grid choice, type conversion, transforms.

Files with several grids, other value types, level sets and frustums are written by Blender's bundled
OpenVDB 12 Python module (in a subprocess: the native tests never import bpy themselves).
"""

import concurrent.futures
import json
import os

import numpy as np
import pytest

import pcvr_native as pn
from _io_helpers import HAVE_BPY, affine_matrix, describe, run_blender_openvdb, run_python, sparse_volume

needs_bpy = pytest.mark.skipif(not HAVE_BPY, reason="bpy (Blender's bundled openvdb module) is not installed")


def dense_of(grid):
    """(values over index_bbox, origin) through the renderer's block view."""
    return grid.to_dense(), np.array(grid.index_bbox[0])


def assert_matches_array(grid, values, background=0.0):
    """The grid's active voxels are exactly the array's non-background voxels, with the same values."""
    active = values != background
    assert grid.active_voxel_count == int(active.sum())
    idx = np.argwhere(active)
    assert grid.index_bbox == (tuple(int(v) for v in idx.min(0)), tuple(int(v) for v in idx.max(0)))
    assert grid.value_range == pytest.approx((float(values[active].min()), float(values[active].max())))
    dense, origin = dense_of(grid)
    lo, hi = origin, origin + np.array(dense.shape)
    expected = np.where(active, values, 0.0)[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]]
    np.testing.assert_array_equal(dense, expected)


# ------------------------------------------------------------------------------------------------
# Grids built in memory and written by us

@pytest.mark.parametrize("compression", ["blosc", "zip", "none"])
def test_round_trip_keeps_values_transform_and_inactive_background(tmp_path, compression):
    values = sparse_volume()
    m = affine_matrix()
    grid = pn.Grid.from_dense(values, m)
    assert_matches_array(grid, values)

    path = tmp_path / "round_trip.vdb"
    grid.write_vdb(path, compression=compression)
    back = pn.read_vdb(path)
    assert back.name == "density"
    assert back.source_path == str(path)
    np.testing.assert_allclose(back.index_to_world, m, rtol=0, atol=1e-12)
    assert_matches_array(back, values)
    (info,) = pn.list_grids(path)
    assert info.pop("metadata")["creator"] == "pcvr"
    assert info == {"name": "density", "value_type": "float", "grid_class": "fog volume",
                    "active_voxels": int((values != 0).sum())}


def test_background_voxels_stay_inactive_and_others_stay_active(tmp_path):
    values = np.full((9, 10, 11), 0.25, np.float32)
    values[1:4, 2:5, 3:9] = 0.0  # equal to 0, not to the background: active
    values[7, 8, 9] = 3.0
    grid = pn.Grid.from_dense(values, np.eye(4), background=0.25)
    assert grid.active_voxel_count == 3 * 3 * 6 + 1
    assert grid.value_range == (0.0, 3.0)
    assert grid.index_bbox == ((1, 2, 3), (7, 8, 9))
    dense = grid.to_dense(fill=-1.0)
    assert dense[0, 0, 0] == 0.0 and dense[6, 6, 6] == 3.0 and dense[6, 0, 0] == -1.0

    grid.write_vdb(tmp_path / "bg.vdb")
    back = pn.read_vdb(tmp_path / "bg.vdb")
    assert back.active_voxel_count == grid.active_voxel_count
    np.testing.assert_array_equal(back.to_dense(fill=-1.0), dense)


def test_constant_regions_become_tiles_that_expand_to_blocks():
    values = np.ones((64, 64, 64), np.float32)  # one 128^3 internal node's worth of constant leaves
    grid = pn.Grid.from_dense(values, np.eye(4))
    assert grid.active_voxel_count == 64 ** 3
    assert grid.block_count == 64 ** 3 // 512
    np.testing.assert_array_equal(grid.to_dense(), values)


def test_empty_grid(tmp_path):
    grid = pn.Grid.from_dense(np.zeros((4, 5, 6), np.float32), np.eye(4))
    assert grid.active_voxel_count == 0
    assert grid.index_bbox == ((0, 0, 0), (0, 0, 0))
    assert grid.value_range == (0.0, 0.0)
    assert grid.block_count == 0
    assert grid.to_dense().shape == (0, 0, 0)
    grid.write_vdb(tmp_path / "empty.vdb")
    assert pn.read_vdb(tmp_path / "empty.vdb").active_voxel_count == 0


@pytest.mark.parametrize("make", [
    lambda a: a.astype(np.float64),
    lambda a: (a * 10).astype(np.int32),
    lambda a: np.asfortranarray(a),
    lambda a: a[::-1, :, ::2],
    lambda a: a.tolist(),
], ids=["float64", "int32", "fortran", "strided", "list"])
def test_from_dense_accepts_any_numeric_array(make):
    values = sparse_volume(shape=(12, 10, 8))
    source = make(values)
    expected = np.asarray(source, dtype=np.float32)
    assert_matches_array(pn.Grid.from_dense(source, np.eye(4)), expected)


@pytest.mark.parametrize("matrix, message", [
    (np.diag([1.0, 0.0, 1.0, 1.0]), "singular"),
    (np.where(np.eye(4) > 0, np.nan, 0.0), "finite"),
    (np.eye(3), "shape"),
    (np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0.5, 1.0]]), "affine"),
])
def test_from_dense_rejects_bad_transforms(matrix, message):
    with pytest.raises(pn.GridError, match=message):
        pn.Grid.from_dense(np.ones((2, 2, 2), np.float32), matrix)
    grid = pn.Grid.from_dense(np.ones((2, 2, 2), np.float32), np.eye(4))
    with pytest.raises(pn.GridError, match=message):
        grid.with_index_to_world(matrix)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_from_dense_rejects_non_finite_values(bad):
    values = np.zeros((3, 4, 5), np.float32)
    values[1, 2, 3] = bad
    with pytest.raises(pn.GridError, match=r"\[1, 2, 3\]"):
        pn.Grid.from_dense(values, np.eye(4))


def test_from_dense_rejects_arrays_that_are_not_3d():
    with pytest.raises(ValueError, match="3-D"):
        pn.Grid.from_dense(np.ones((4, 4), np.float32), np.eye(4))


def test_with_index_to_world_shares_voxels_and_is_written(tmp_path):
    values = sparse_volume(shape=(16, 16, 16))
    grid = pn.Grid.from_dense(values, np.eye(4))
    moved = grid.with_index_to_world(affine_matrix(seed=5))
    np.testing.assert_array_equal(grid.index_to_world, np.eye(4))
    np.testing.assert_allclose(moved.index_to_world, affine_matrix(seed=5), rtol=0, atol=0)
    assert moved.active_voxel_count == grid.active_voxel_count
    np.testing.assert_array_equal(moved.to_dense(), grid.to_dense())

    moved.write_vdb(tmp_path / "moved.vdb", name="smoke")
    back = pn.read_vdb(tmp_path / "moved.vdb")
    assert back.name == "smoke"
    np.testing.assert_allclose(back.index_to_world, affine_matrix(seed=5), rtol=0, atol=1e-12)


def test_write_replaces_existing_file_and_leaves_no_temporaries(tmp_path):
    path = tmp_path / "out.vdb"
    path.write_bytes(b"old contents")
    grid = pn.Grid.from_dense(sparse_volume(), np.eye(4))
    grid.write_vdb(str(path))
    assert pn.read_vdb(path).active_voxel_count == grid.active_voxel_count
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.vdb"]


def test_write_rejects_unknown_compression(tmp_path):
    grid = pn.Grid.from_dense(np.ones((2, 2, 2), np.float32), np.eye(4))
    with pytest.raises(ValueError, match="compression"):
        grid.write_vdb(tmp_path / "x.vdb", compression="lzma")
    assert list(tmp_path.iterdir()) == []


def test_repr_names_grid_and_file(tmp_path):
    grid = pn.Grid.from_dense(sparse_volume(), np.eye(4), name="smoke")
    assert "smoke" in repr(grid) and "active voxels" in repr(grid)
    assert grid.source_path is None
    grid.write_vdb(tmp_path / "r.vdb", name="smoke")
    assert str(tmp_path / "r.vdb") in repr(pn.read_vdb(tmp_path / "r.vdb"))


def test_concurrent_reads_and_block_builds(tmp_path):
    values = sparse_volume(shape=(40, 40, 40), seed=9)
    pn.Grid.from_dense(values, np.eye(4)).write_vdb(tmp_path / "c.vdb")
    shared = pn.read_vdb(tmp_path / "c.vdb")

    def work(_):
        g = pn.read_vdb(tmp_path / "c.vdb")
        return g.active_voxel_count, g.block_count, shared.block_count

    with concurrent.futures.ThreadPoolExecutor(8) as pool:
        results = set(pool.map(work, range(16)))
    assert len(results) == 1
    assert_matches_array(shared, values)


# ------------------------------------------------------------------------------------------------
# Files written by Blender's OpenVDB

@pytest.fixture(scope="module")
def blender_files(tmp_path_factory):
    """Files written by Blender's OpenVDB 12, plus the arrays they hold (as .npy)."""
    if not HAVE_BPY:
        pytest.skip("bpy (Blender's bundled openvdb module) is not installed")
    d = tmp_path_factory.mktemp("blender_vdb")
    run_blender_openvdb(f"""
        import os
        d = {str(d)!r}
        rng = np.random.default_rng(3)
        saved = []
        def arr(shape, dtype, scale=5):  # saved as arr_0.npy, arr_1.npy, ... in call order
            a = np.where(rng.random(shape) < 0.2, rng.uniform(0.5, scale, shape), 0).astype(dtype)
            np.save(os.path.join(d, 'arr_%d.npy' % len(saved)), a)
            saved.append(a)
            return a
        def grid(cls, name, a, cls_name='fog volume'):
            g = cls(); g.name = name; g.copyFromArray(a); g.gridClass = getattr(vdb.GridClass, cls_name.upper().replace(' ', '_'))
            return g

        # Several grids; 'density' is not the first; one vector grid; one instance (shared tree).
        temperature = grid(vdb.FloatGrid, 'temperature', arr((10, 10, 10), np.float32))
        density = grid(vdb.FloatGrid, 'density', arr((12, 11, 10), np.float32))
        density.transform = vdb.createLinearTransform([[0.5, 0, 0, 0], [0, 0.25, 0.1, 0], [0, 0, 2, 0], [1, 2, 3, 1]])
        vel = vdb.Vec3SGrid(); vel.name = 'velocity'
        vel.copyFromArray(np.ones((3, 3, 3, 3), np.float32))
        flame_i = grid(vdb.Int32Grid, 'flags', arr((6, 6, 6), np.int32, 100))
        heat_d = grid(vdb.DoubleGrid, 'heat', arr((7, 8, 9), np.float64))
        big_i = grid(vdb.Int64Grid, 'big', arr((5, 5, 5), np.int64, 1000))
        inst = density.copy(); inst.name = 'density_instance'
        vdb.write(os.path.join(d, 'multi.vdb'), [temperature, vel, density, flame_i, heat_d, big_i, inst])

        # No 'density': the first float grid wins, even after a vector grid.
        vdb.write(os.path.join(d, 'no_density.vdb'), [vel, flame_i, temperature, heat_d])
        vdb.write(os.path.join(d, 'only_vector.vdb'), [vel])
        vdb.write(os.path.join(d, 'duplicate_names.vdb'), [temperature, density.deepCopy(), temperature.deepCopy()])

        sphere = vdb.createLevelSetSphere(radius=6.0, center=(0, 0, 0), voxelSize=0.5, halfWidth=3.0)
        sphere.name = 'surface'
        vdb.write(os.path.join(d, 'sphere.vdb'), [sphere])

        fr = vdb.FloatGrid(); fr.name = 'density'; fr.copyFromArray(np.ones((4, 4, 4), np.float32))
        fr.transform = vdb.createFrustumTransform((0, 0, 0), (7, 7, 7), 0.5, 2.0)
        vdb.write(os.path.join(d, 'frustum.vdb'), [fr])

        mask = vdb.BoolGrid(); mask.name = 'mask'
        mask_array = rng.random((9, 9, 9)) < 0.3
        mask.copyFromArray(mask_array)
        np.save(os.path.join(d, 'bool.npy'), mask_array)
        vdb.write(os.path.join(d, 'bool.vdb'), [mask])

        half = vdb.FloatGrid(); half.name = 'density'; half.copyFromArray(np.load(os.path.join(d, 'arr_1.npy')))
        half.saveFloatAsHalf = True
        vdb.write(os.path.join(d, 'half.vdb'), [half])
    """)
    return d


@needs_bpy
def test_list_grids_of_a_multi_grid_file(blender_files):
    path = blender_files / "multi.vdb"
    arrays = [np.load(blender_files / f"arr_{i}.npy") for i in range(5)]
    grids = pn.list_grids(str(path))
    assert [g["name"] for g in grids] == ["temperature", "velocity", "density", "flags", "heat", "big",
                                         "density_instance"]
    assert [g["value_type"] for g in grids] == ["float", "vec3s", "float", "int32", "double", "int64", "float"]
    assert {g["grid_class"] for g in grids if g["name"] != "velocity"} == {"fog volume"}
    assert grids[0]["active_voxels"] == np.count_nonzero(arrays[0])
    assert grids[1]["active_voxels"] == 27
    assert grids[2]["active_voxels"] == grids[6]["active_voxels"] == np.count_nonzero(arrays[1])
    assert grids[3]["active_voxels"] == np.count_nonzero(arrays[2])


@needs_bpy
def test_default_grid_is_density_then_first_float_grid(blender_files):
    multi = pn.read_vdb(blender_files / "multi.vdb")
    assert multi.name == "density"
    assert_matches_array(multi, np.load(blender_files / "arr_1.npy"))
    # Blender's row-vector matrix, transposed: world = M @ [i, j, k, 1].
    expected = np.array([[0.5, 0, 0, 1], [0, 0.25, 0, 2], [0, 0.1, 2, 3], [0, 0, 0, 1]])
    np.testing.assert_allclose(multi.index_to_world, expected, rtol=0, atol=1e-12)

    assert pn.read_vdb(blender_files / "no_density.vdb").name == "temperature"
    assert pn.read_vdb(blender_files / "multi.vdb", grid="").name == "density"


@needs_bpy
def test_double_and_integer_grids_are_converted_to_float(blender_files):
    path = blender_files / "multi.vdb"
    for name, index in [("flags", 2), ("heat", 3), ("big", 4)]:
        grid = pn.read_vdb(path, grid=name)
        assert grid.name == name
        assert_matches_array(grid, np.load(blender_files / f"arr_{index}.npy").astype(np.float32))


@needs_bpy
def test_bool_grid_reads_as_ones(blender_files):
    grid = pn.read_vdb(blender_files / "bool.vdb")
    assert grid.name == "mask"
    assert_matches_array(grid, np.load(blender_files / "bool.npy").astype(np.float32))


@needs_bpy
def test_instance_grid_reads_its_parents_voxels(blender_files):
    a = pn.read_vdb(blender_files / "multi.vdb", grid="density")
    b = pn.read_vdb(blender_files / "multi.vdb", grid="density_instance")
    assert b.name == "density_instance"
    np.testing.assert_array_equal(a.to_dense(), b.to_dense())


@needs_bpy
def test_vector_grids_are_rejected_with_file_grid_and_type(blender_files):
    path = str(blender_files / "multi.vdb")
    with pytest.raises(pn.GridError) as err:
        pn.read_vdb(path, grid="velocity")
    message = str(err.value)
    assert path in message and "velocity" in message and "vec3s" in message
    assert "vector grids are not supported" in message
    with pytest.raises(pn.GridError, match="no scalar grid"):
        pn.read_vdb(blender_files / "only_vector.vdb")


@needs_bpy
def test_unknown_grid_lists_the_grids_that_exist(blender_files):
    path = str(blender_files / "multi.vdb")
    with pytest.raises(pn.GridError) as err:
        pn.read_vdb(path, grid="smoke")
    message = str(err.value)
    assert path in message and "'smoke'" in message
    for name in ["temperature", "velocity", "density", "flags", "heat"]:
        assert name in message
    assert isinstance(err.value, ValueError)


@needs_bpy
def test_duplicate_grid_names_are_listed_with_an_index(blender_files):
    path = blender_files / "duplicate_names.vdb"
    names = [g["name"] for g in pn.list_grids(path)]
    assert names[1] == "density"
    assert names[0] != names[2] and {names[0], names[2]} <= {"temperature", "temperature[0]", "temperature[1]"}
    first, second = pn.read_vdb(path, grid=names[0]), pn.read_vdb(path, grid=names[2])
    np.testing.assert_array_equal(first.to_dense(), second.to_dense())


@needs_bpy
def test_level_set_becomes_fog_volume(blender_files):
    info = pn.list_grids(blender_files / "sphere.vdb")
    assert info[0]["grid_class"] == "level set"
    grid = pn.read_vdb(blender_files / "sphere.vdb")
    assert grid.name == "surface"
    lo, hi = grid.value_range
    assert 0.0 < lo < 0.5 and hi == 1.0
    # Radius 6 world units = 12 voxels; the fog ends at the zero crossing.
    (i0, j0, k0), (i1, j1, k1) = grid.index_bbox
    assert -13 <= i0 <= -11 and 11 <= i1 <= 13
    dense = grid.to_dense()
    centre = dense[-i0, -j0, -k0]
    assert centre == 1.0
    # The interior is filled (active), not just the narrow band.
    assert grid.active_voxel_count > 0.9 * (4 / 3) * np.pi * 11 ** 3


@needs_bpy
def test_frustum_transform_is_rejected(blender_files):
    path = str(blender_files / "frustum.vdb")
    with pytest.raises(pn.GridError, match="frustum") as err:
        pn.read_vdb(path)
    assert path in str(err.value) and "density" in str(err.value)


@needs_bpy
def test_half_float_file(blender_files):
    grid = pn.read_vdb(blender_files / "half.vdb")
    expected = np.load(blender_files / "arr_1.npy").astype(np.float16).astype(np.float32)
    assert_matches_array(grid, expected)


@needs_bpy
def test_blender_reads_what_we_write(tmp_path):
    values = sparse_volume(shape=(20, 18, 16), seed=4)
    m = affine_matrix(seed=6)
    pn.Grid.from_dense(values, m).write_vdb(tmp_path / "ours.vdb", name="smoke")
    out = run_blender_openvdb(f"""
        import json
        grid = vdb.read({str(tmp_path / 'ours.vdb')!r}, 'smoke')
        a = np.zeros({values.shape}, np.float32)
        grid.copyToArray(a)
        np.save({str(tmp_path / 'back.npy')!r}, a)
        corners = [grid.transform.indexToWorld(p) for p in [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]]
        print(json.dumps({{"class": str(grid.gridClass), "active": grid.activeVoxelCount(),
                          "corners": [list(c) for c in corners]}}))
    """)
    result = json.loads(out.stdout.strip().splitlines()[-1])
    np.testing.assert_array_equal(np.load(tmp_path / "back.npy"), values)
    assert result["active"] == np.count_nonzero(values)
    assert "FOG" in result["class"].upper()
    origin, *axes = np.array(result["corners"])
    np.testing.assert_allclose(origin, m[:3, 3], atol=1e-12)
    np.testing.assert_allclose(np.array(axes).T - origin[:, None], m[:3, :3], atol=1e-12)


def test_format_225_reads_as_224_without_a_console_warning(tmp_path):
    """OpenVDB 13 (Blender 5.3's) writes format 225, which only announces its half-float grid type: a float grid
    is stored as in 224. Ours, read with its format number made 225, gives the same grid and prints nothing
    (OpenVDB 10's header reader would log "unsupported VDB file format" on the console for every such file)."""
    values = sparse_volume(shape=(12, 10, 8), seed=8)
    pn.Grid.from_dense(values, affine_matrix(seed=9)).write_vdb(tmp_path / "224.vdb")
    data = bytearray((tmp_path / "224.vdb").read_bytes())
    assert int.from_bytes(data[8:12], "little") == 224
    data[8:12] = (225).to_bytes(4, "little")
    (tmp_path / "225.vdb").write_bytes(data)
    proc = run_python(f"""
        import numpy as np, pcvr_native as pn
        a, b = (pn.read_vdb({str(tmp_path)!r} + name) for name in ("/224.vdb", "/225.vdb"))
        assert np.array_equal(a.to_dense(), b.to_dense()) and np.array_equal(a.index_to_world, b.index_to_world)
        assert pn.list_grids({str(tmp_path / '225.vdb')!r})[0]["active_voxels"] == a.active_voxel_count
        assert pn.stream_vdb({str(tmp_path / '225.vdb')!r}).active_voxel_count == a.active_voxel_count
        print("same")
    """)
    assert proc.returncode == 0 and proc.stdout.strip() == "same", describe(proc)
    assert "unsupported VDB file format" not in proc.stderr + proc.stdout
