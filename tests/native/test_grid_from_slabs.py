"""Grid.from_slabs (a grid built a slab of i-planes at a time) and write_vdb's string metadata."""

import numpy as np
import pytest

import pcvr_native as pn

M = np.array([[0.5, 0.1, 0.0, -3.0], [0.0, 0.7, 0.2, 1.0], [0.1, 0.0, 1.2, 2.0], [0, 0, 0, 1.0]])


def slabs_of(values, sizes):
    start = 0
    for size in sizes:
        yield values[start:start + size]
        start += size


@pytest.mark.parametrize("sizes", [[21], [1] * 21, [3, 5, 8, 5], [7, 7, 7], [0, 10, 0, 11]])
def test_slabs_build_the_grid_from_dense_builds(rng, sizes):
    """Any cut into slabs, aligned with the 8^3 leaves or not, gives the same active voxels and values."""
    values = rng.normal(size=(21, 13, 17)).astype(np.float32)
    values[values < -0.5] = -0.5          # some voxels at the background
    values[:, :, :4] = -0.5               # and whole runs of them
    whole = pn.Grid.from_dense(values, M, background=-0.5)
    sliced = pn.Grid.from_slabs(slabs_of(values, sizes), values.shape, M, background=-0.5)
    assert sliced.active_voxel_count == whole.active_voxel_count
    assert sliced.index_bbox == whole.index_bbox and sliced.background == -0.5
    np.testing.assert_array_equal(sliced.to_dense(fill=9.0), whole.to_dense(fill=9.0))
    np.testing.assert_array_equal(sliced.index_to_world, whole.index_to_world)


def test_slabs_of_the_wrong_count_or_shape_are_refused(rng):
    values = rng.random((6, 4, 5), dtype=np.float32)
    with pytest.raises(pn.GridError, match="4 of 6 planes added"):
        pn.Grid.from_slabs(slabs_of(values, [2, 2]), values.shape, M)
    with pytest.raises(pn.GridError, match="8 planes added to a grid of 6"):
        pn.Grid.from_slabs(slabs_of(np.concatenate([values, values]), [4, 4]), values.shape, M)
    with pytest.raises(ValueError, match=r"4 x 5 voxels per plane, got shape \(2, 5, 4\)"):
        pn.Grid.from_slabs([values[:2].transpose(0, 2, 1)], values.shape, M)


def test_nan_is_named_at_its_index_in_the_whole_grid(rng):
    values = rng.random((6, 4, 5), dtype=np.float32)
    values[4, 2, 3] = np.nan
    with pytest.raises(pn.GridError, match=r"NaN at \[4, 2, 3\]"):
        pn.Grid.from_slabs(slabs_of(values, [3, 3]), values.shape, M)


def test_an_error_in_the_slabs_iterable_propagates(rng):
    def failing():
        yield np.zeros((2, 4, 5), np.float32)
        raise OSError("disk gone")

    with pytest.raises(OSError, match="disk gone"):
        pn.Grid.from_slabs(failing(), (6, 4, 5), M)


def test_write_vdb_keeps_string_metadata(tmp_path, rng):
    grid = pn.Grid.from_dense(rng.random((3, 4, 5), dtype=np.float32), M)
    path = tmp_path / "meta.vdb"
    grid.write_vdb(path, metadata={"pcvr_modality": "CT", "pcvr_units": "HU"})
    meta = pn.list_grids(path)[0]["metadata"]
    assert meta["pcvr_modality"] == "CT" and meta["pcvr_units"] == "HU" and meta["name"] == "density"
