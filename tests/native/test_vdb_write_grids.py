"""pn.write_vdb: several grids in one .vdb file, float and vector, as simulation caches hold them ('density',
'flame', 'color'); read back by our reader and by Blender's bundled OpenVDB."""

import json

import numpy as np
import pcvr_native as pn
import pytest

from _io_helpers import HAVE_BPY, affine_matrix, file_grids, run_blender_openvdb, sparse_volume

SHAPE = (12, 10, 9)


@pytest.fixture
def smoke():
    """{name: float32 array}: a density, a flame inside it, and a colour's three components, zero (inactive)
    where there is no density except the red one, which reaches one voxel further, so that the vector grid's
    voxels are the union of its components'."""
    density = sparse_volume(SHAPE, fill_fraction=0.3, seed=11)
    flame = np.where(density > 2.0, density / 5.0, 0.0).astype(np.float32)
    rng = np.random.default_rng(12)
    colour = np.where(density[..., None] > 0, rng.uniform(0.05, 1.0, SHAPE + (3,)), 0.0).astype(np.float32)
    colour[0, 0, 0] = (0.5, 0.0, 0.0) if density[0, 0, 0] == 0 else colour[0, 0, 0]
    return {"density": density, "flame": flame, "colour": colour}


def dense(grid, shape):
    """The grid's values over [0, shape) (inactive voxels at the background)."""
    out = np.full(shape, grid.background, np.float32)
    if grid.active_voxel_count:
        (i0, j0, k0), (i1, j1, k1) = grid.index_bbox
        out[i0:i1 + 1, j0:j1 + 1, k0:k1 + 1] = grid.to_dense(fill=grid.background)
    return out


def test_float_and_vector_grids_read_back_in_order_with_their_metadata(tmp_path, smoke):
    matrix = affine_matrix(seed=3)
    path = tmp_path / "cache.vdb"
    pn.write_vdb(path, file_grids(smoke, matrix), metadata={"flame": {"units": "none"}})

    listed = pn.list_grids(path)
    assert [(g["name"], g["value_type"], g["grid_class"]) for g in listed] == [
        ("density", "float", "fog volume"), ("flame", "float", "fog volume"), ("colour", "vec3s", "fog volume")]
    assert listed[1]["metadata"]["units"] == "none" and "units" not in listed[0]["metadata"]
    for name in ("density", "flame"):
        grid = pn.read_vdb(path, name)
        np.testing.assert_array_equal(dense(grid, SHAPE), smoke[name])
        np.testing.assert_allclose(grid.index_to_world, matrix, atol=1e-12)
    union = np.count_nonzero(np.any(smoke["colour"] != 0, axis=-1))
    assert listed[2]["active_voxels"] == union
    for c, grid in enumerate(pn.read_vdb_vector(path, "colour")):
        np.testing.assert_array_equal(dense(grid, SHAPE), smoke["colour"][..., c])
        assert grid.active_voxel_count == union


def test_a_single_grid_writes_as_grid_write_vdb_does(tmp_path, smoke):
    grid = pn.Grid.from_dense(smoke["density"], affine_matrix(seed=4))
    pn.write_vdb(tmp_path / "many.vdb", {"density": grid}, compression="zip")
    grid.write_vdb(tmp_path / "one.vdb", name="density", compression="zip")
    assert pn.list_grids(tmp_path / "many.vdb") == pn.list_grids(tmp_path / "one.vdb")


def test_grids_that_cannot_be_written_are_refused_by_name_and_nothing_is_written(tmp_path, smoke):
    density = pn.Grid.from_dense(smoke["density"], np.eye(4))
    moved = pn.Grid.from_dense(smoke["flame"], affine_matrix(seed=5))
    path = tmp_path / "bad.vdb"
    with pytest.raises(pn.GridError, match="'colour'.*different index-to-world"):
        pn.write_vdb(path, {"density": density, "colour": (density, moved, density)})
    with pytest.raises(TypeError, match="'colour' must be a Grid or a sequence of three Grids"):
        pn.write_vdb(path, {"colour": (density, density)})
    with pytest.raises(TypeError, match="'colour' must be a Grid"):
        pn.write_vdb(path, {"colour": (density, density, "red")})
    with pytest.raises(pn.GridError, match="no grids to write"):
        pn.write_vdb(path, {})
    with pytest.raises(ValueError, match="metadata names grid 'smoke', which is not written"):
        pn.write_vdb(path, {"density": density}, metadata={"smoke": {"a": "b"}})
    with pytest.raises(ValueError, match="compression"):
        pn.write_vdb(path, {"density": density}, compression="lz4")
    assert list(tmp_path.iterdir()) == []


def test_a_failed_write_is_an_os_error_naming_the_file(tmp_path, smoke):
    density = pn.Grid.from_dense(smoke["density"], np.eye(4))
    missing = tmp_path / "no such folder" / "cache.vdb"
    with pytest.raises(OSError, match="no such folder"):
        pn.write_vdb(missing, {"density": density})


@pytest.mark.skipif(not HAVE_BPY, reason="bpy (Blender's bundled openvdb module) is not installed")
def test_blender_reads_the_vector_grid(tmp_path, smoke):
    path = tmp_path / "cache.vdb"
    pn.write_vdb(path, file_grids(smoke, np.diag([0.5, 0.5, 0.5, 1.0])))
    out = run_blender_openvdb(f"""
        import json
        colour = vdb.read({str(path)!r}, 'colour')
        a = np.zeros({SHAPE + (3,)}, np.float32)
        colour.copyToArray(a)
        np.save({str(tmp_path / 'back.npy')!r}, a)
        print(json.dumps({{"type": colour.valueTypeName, "class": str(colour.gridClass)}}))
    """)
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["type"] == "vec3s" and "FOG" in result["class"].upper()
    np.testing.assert_array_equal(np.load(tmp_path / "back.npy"), smoke["colour"])
