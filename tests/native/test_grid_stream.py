"""Big volumes: a GridStream (pcvr_native.stream_vdb) leaves the voxel values in the file and render_xray
reads them a batch of 128^3 regions at a time, so memory stays bounded whatever the file's size, and the
image is the whole grid's: an X-ray adds up voxels, so the batches' images add up to it.
"""

from __future__ import annotations

import os
import textwrap

import numpy as np
import pytest

import pcvr_native as pn

from _io_helpers import HAVE_BPY, affine_matrix, describe, run_blender_openvdb, run_python, sparse_volume
from sanitized import measures_memory
from xray_helpers import frame_ortho, frame_perspective, rel_rmse

MiB = 1 << 20
VIEW = (0.3, -0.5, -0.8)


def smooth_field(n, seed=0):
    """An n^3 field that fills its box (every leaf active), with detail at a few voxels' scale."""
    x = np.linspace(-1.0, 1.0, n, dtype=np.float32)
    r2 = x[:, None, None] ** 2 + x[None, :, None] ** 2 + x[None, None, :] ** 2
    ripple = np.sin(40 * x[:, None, None] + seed) * np.cos(33 * x[None, :, None]) * np.cos(21 * x[None, None, :])
    return (np.exp(-3 * r2) * (1 + 0.3 * ripple)).astype(np.float32)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A 160^3 field spanning 8 regions (3.0 MiB of values a region at most), and a sparse one with a tile."""
    d = tmp_path_factory.mktemp("streams")
    xf = affine_matrix()
    values = smooth_field(160)
    values[values < 0.06] = 0  # sparse corners: some regions hold few leaves
    pn.Grid.from_dense(values, xf).write_vdb(str(d / "field.vdb"))
    pn.Grid.from_dense(sparse_volume(), xf).write_vdb(str(d / "sparse.vdb"), compression="none")
    return d


def field_view(grid, projection, magnification=1.5):
    frame = frame_ortho if projection == "orthographic" else frame_perspective
    return frame((np.ones((160, 160, 160)), grid.index_to_world), magnification, direction=VIEW).camera()


def render_streamed(path, cam, **kwargs):
    """render_xray of the file's grid streamed a batch per region; checks every voxel was splatted once."""
    stats = {}
    image = pn.render_xray(pn.stream_vdb(path, batch_bytes=1), cam, stats=stats, **kwargs)
    assert stats["batches"] == 7  # 160^3 spans 2 x 2 x 2 regions of 128^3; the threshold emptied the far corner
    assert stats["voxels"] == pn.stream_vdb(path).active_voxel_count
    return image


@pytest.mark.parametrize("method, projection", [
    ("pcvr", "orthographic"), ("regular", "orthographic"), ("bilinear_spread", "orthographic"), ("exact", "orthographic"),
    ("regular", "perspective"), ("bilinear_spread", "perspective"), ("exact", "perspective")])
def test_a_streamed_grid_renders_as_the_grid_read_whole(files, method, projection):
    """A batch per region gives the image of the grid read whole, up to float rounding (the batches' images
    are summed in another order: measured 1.1e-7 of the peak)."""
    path = str(files / "field.vdb")
    grid = pn.read_vdb(path)
    cam = field_view(grid, projection)
    step = 4 if method == "exact" else 1
    whole = pn.render_xray(grid, cam, method=method, pixel_step=step)
    streamed = render_streamed(path, cam, method=method, pixel_step=step)
    np.testing.assert_allclose(streamed, whole, rtol=0, atol=1e-6 * whole.max())


def test_a_streamed_perspective_is_as_accurate_as_the_grid_read_whole(files):
    """In perspective, pcvr's depth bands count from the least magnification of what is splatted, which
    differs from batch to batch: the strides differ (0.02% of the image apart), not the accuracy (relative
    RMSE against exact measured 0.1461% whole, 0.1464% streamed)."""
    path = str(files / "field.vdb")
    grid = pn.read_vdb(path)
    cam = field_view(grid, "perspective")
    exact = pn.render_xray(grid, cam, method="exact")
    whole_error = rel_rmse(pn.render_xray(grid, cam), exact)
    assert rel_rmse(render_streamed(path, cam), exact) < 1.01 * whole_error


def test_a_stream_knows_what_the_file_holds_before_reading_values(files):
    path = str(files / "sparse.vdb")
    grid, stream = pn.read_vdb(path), pn.stream_vdb(path)
    assert stream.name == grid.name == "density"
    assert stream.active_voxel_count == grid.active_voxel_count
    assert stream.index_bbox == grid.index_bbox
    assert stream.background == grid.background
    np.testing.assert_array_equal(stream.index_to_world, grid.index_to_world)
    assert stream.value_range == grid.value_range  # this one reads the file
    # sparse_volume's constant 8^3 block is a tile, not a leaf: it comes with the first batch.
    assert stream.leaf_count < grid.block_count
    assert stream.value_bytes == stream.leaf_count * 512 * 4
    assert "GridStream 'density'" in repr(stream)


def test_streams_and_grids_mix_placed_and_scaled(files):
    """Streams take with_index_to_world and density_scale like grids, in any order in the sequence."""
    field, sparse = pn.read_vdb(str(files / "field.vdb")), pn.read_vdb(str(files / "sparse.vdb"))
    moved = np.eye(4)
    moved[:3, 3] = (20.0, 0.0, 5.0)
    sparse_moved = sparse.with_index_to_world(moved @ sparse.index_to_world)
    stream_moved = pn.stream_vdb(str(files / "sparse.vdb"))
    stream_moved = stream_moved.with_index_to_world(moved @ stream_moved.index_to_world)
    cam = frame_ortho((np.ones((160, 160, 160)), field.index_to_world), 1.0, direction=VIEW, margin=40).camera()
    scales = [2.0, 0.5]
    expected = pn.render_xray([sparse_moved, field], cam, density_scale=scales)
    mixed = pn.render_xray([stream_moved, field], cam, density_scale=scales)
    np.testing.assert_allclose(mixed, expected, rtol=0, atol=1e-6 * expected.max())


def test_progress_runs_over_the_batches_and_cancel_stops_them(files):
    stream = pn.stream_vdb(str(files / "field.vdb"), batch_bytes=1)
    cam = frame_ortho((np.ones((160, 160, 160)), stream.index_to_world), 4.0, direction=VIEW).camera()
    seen = []
    pn.render_xray(stream, cam, method="regular", progress=seen.append)
    assert seen == sorted(seen) and seen[-1] == 1.0
    with pytest.raises(pn.RenderCancelled):
        pn.render_xray(stream, cam, method="regular", cancel=lambda: len(seen) > 0)


def test_a_corrupt_file_fails_on_opening_naming_it(files, tmp_path):
    data = (files / "sparse.vdb").read_bytes()
    truncated = tmp_path / "truncated.vdb"
    truncated.write_bytes(data[: len(data) - 1000])
    with pytest.raises(pn.VDBReadError, match="truncated.vdb"):
        pn.stream_vdb(str(truncated))


def test_a_file_changed_after_opening_is_not_read(files, tmp_path):
    """The stream holds the file's layout: a rewritten file would be read at the old offsets."""
    path = tmp_path / "changing.vdb"
    pn.Grid.from_dense(smooth_field(24), np.eye(4)).write_vdb(str(path))
    stream = pn.stream_vdb(str(path))
    pn.Grid.from_dense(smooth_field(40), np.eye(4)).write_vdb(str(path))
    cam = frame_ortho((np.ones((24, 24, 24)), np.eye(4)), 1.0).camera()
    with pytest.raises(pn.VDBReadError, match="changed since 'density' was opened"):
        pn.render_xray(stream, cam)


@pytest.mark.skipif(not HAVE_BPY, reason="bpy (Blender's bundled openvdb module) is not installed")
def test_grids_that_cannot_be_streamed_say_to_read_them_whole(tmp_path):
    """Double grids (converted as a whole), level sets (converted to fog as a whole) and half floats."""
    run_blender_openvdb(f"""
        d = {str(tmp_path)!r}
        heat = vdb.DoubleGrid(); heat.name = 'heat'; heat.copyFromArray(np.ones((9, 9, 9)))
        sphere = vdb.createLevelSetSphere(radius=6.0, center=(0, 0, 0), voxelSize=0.5, halfWidth=3.0)
        half = vdb.FloatGrid(); half.name = 'density'
        half.copyFromArray(np.linspace(0.5, 2, 40 ** 3).reshape(40, 40, 40).astype(np.float32))
        half.saveFloatAsHalf = True
        vdb.write(d + '/heat.vdb', [heat]); vdb.write(d + '/sphere.vdb', [sphere]); vdb.write(d + '/half.vdb', [half])
    """)
    for name in ("heat", "sphere"):
        with pytest.raises(pn.GridError, match=f"{name}.vdb.*read it whole"):
            pn.stream_vdb(str(tmp_path / f"{name}.vdb"))
    half = str(tmp_path / "half.vdb")
    cam = frame_ortho((np.ones((40, 40, 40)), np.eye(4)), 2.0, direction=VIEW).camera()
    np.testing.assert_array_equal(pn.render_xray(pn.stream_vdb(half), cam), pn.render_xray(pn.read_vdb(half), cam))


@measures_memory
def test_a_volume_bigger_than_the_memory_limit_renders_within_it(tmp_path):
    """A 256^3 volume (64 MiB of values) under a 32 MiB limit: the render's peak resident memory above
    what the process held with the stream open stays under the limit (measured 23 MiB: 16 MiB batches of
    two regions, their blocks, the image buffers), where reading the grid whole takes 72 MiB. Run in
    fresh interpreters; the peak (VmHWM) is reset just before the render, so that it is the render's."""
    path = tmp_path / "big.vdb"
    pn.Grid.from_dense(smooth_field(256), np.eye(4)).write_vdb(str(path))
    limit = 32 * MiB
    measure = textwrap.dedent(f"""
        import numpy as np, pcvr_native as pn
        def resident():
            return int(open('/proc/self/statm').read().split()[1]) * 4096
        def peak_resident():
            return next(int(line.split()[1]) * 1024 for line in open('/proc/self/status') if line.startswith('VmHWM'))
        world_to_camera = np.eye(4); world_to_camera[:3, 3] = (-128, -128, -600)
        projection = np.diag([1 / 150, 1 / 150, -2 / 1000, 1.0]); projection[2, 3] = -1
        cam = pn.Camera(world_to_camera, projection, 600, 600)
        before = resident()
        grid = pn.{{open}}({str(path)!r})
        opened = resident()
        with open('/proc/self/clear_refs', 'w') as f:
            f.write('5')  # the peak so far (VmHWM) becomes the present
        image = pn.render_xray(grid, cam, memory_limit={limit})
        print(opened - before, peak_resident() - opened, float(image.sum()))
    """)
    results = {}
    for opener in ("stream_vdb", "read_vdb"):
        proc = run_python(measure.replace("{open}", opener))
        assert proc.returncode == 0, describe(proc)
        results[opener] = [float(v) for v in proc.stdout.split()]
    opened, render_peak, total = results["stream_vdb"]
    assert render_peak < limit, f"streamed render peaked {render_peak / MiB:.1f} MiB above the open stream"
    assert opened < 16 * MiB  # the topology: about 100 bytes a leaf, against 2 KiB of values
    assert results["read_vdb"][0] > 64 * MiB  # what the stream saves: the check could fail
    assert total == pytest.approx(results["read_vdb"][2], rel=1e-6)
    os.remove(path)


def test_a_zoomed_out_stream_renders_its_level_from_memory(files, tmp_path):
    """Where a view picks a coarse level (here level 1 at 1/200 of a pixel per voxel) that takes no more
    than a batch, the stream makes the level once, from every batch, and keeps it: the image is the whole
    grid's at that level, and the next render reads nothing from the file (so a file replaced since still
    renders, from the level kept)."""
    path = tmp_path / "field.vdb"
    path.write_bytes((files / "field.vdb").read_bytes())
    grid, stream = pn.read_vdb(str(path)), pn.stream_vdb(str(path))
    cam = field_view(grid, "orthographic", magnification=1 / 200)
    whole_stats, stream_stats = {}, {}
    whole = pn.render_xray(grid, cam, stats=whole_stats)
    streamed = pn.render_xray(stream, cam, stats=stream_stats)
    assert whole_stats["level"] == stream_stats["level"] == 1
    assert stream_stats["voxels"] == whole_stats["voxels"] < grid.active_voxel_count / 7
    np.testing.assert_allclose(streamed, whole, rtol=0, atol=1e-6 * whole.max())
    pn.Grid.from_dense(smooth_field(24), np.eye(4)).write_vdb(str(path))
    np.testing.assert_array_equal(pn.render_xray(stream, cam), streamed)
    with pytest.raises(pn.VDBReadError, match="changed since"):
        pn.render_xray(stream, cam, level=0)


def test_a_zoomed_out_stream_is_supersampled_as_its_grid(files):
    """At 1/24 of a pixel per voxel (1/9 along the voxels' longest projection), level 0, the whole grid renders
    at 24 x 24 sub-pixels a pixel (src/view/level_of_detail.h); every batch of the stream takes the same, chosen over the whole stream's
    box, so the batches' box-averaged images add up to the grid's."""
    path = str(files / "field.vdb")
    grid = pn.read_vdb(path)
    cam = field_view(grid, "orthographic", magnification=1 / 24)
    whole_stats, stream_stats = {}, {}
    whole = pn.render_xray(grid, cam, stats=whole_stats)
    streamed = pn.render_xray(pn.stream_vdb(path, batch_bytes=1), cam, stats=stream_stats)
    assert stream_stats["batches"] == 7
    assert (whole_stats["level"], whole_stats["supersampling"]) == (stream_stats["level"], stream_stats["supersampling"]) == (0, 24)
    np.testing.assert_allclose(streamed, whole, rtol=0, atol=1e-6 * whole.max())


REDUCTIONS = ["mean_over_zero", "mean_over_background", "max_over_background"]


@pytest.mark.parametrize("reduction", REDUCTIONS)
def test_a_stream_level_is_the_grid_level(files, reduction):
    """Level k of a stream, made batch by batch, holds the voxels of Grid.level(k), placed alike."""
    path = str(files / "field.vdb")
    grid, stream = pn.read_vdb(path), pn.stream_vdb(path, batch_bytes=1)
    for k in (1, 3, 7):
        np.testing.assert_array_equal(stream.level(k, reduction).to_dense(), grid.level(k, reduction).to_dense())
        np.testing.assert_allclose(stream.level(k, reduction).index_to_world, grid.level(k, reduction).index_to_world,
                                   rtol=1e-12)
    with pytest.raises(ValueError, match="from 1 to 7"):
        stream.level(8)


@pytest.mark.parametrize("reduction", REDUCTIONS)
def test_tiles_travel_with_their_region(tmp_path, reduction):
    """A constant 8^3 tile and scattered leaves in the second of two regions, over a CT-like background of
    -1000: a level voxel of level 4 or more covers both, and the stream's level is still the grid's (tiles
    travel with the region they lie in)."""
    values = sparse_volume(shape=(160, 36, 30), seed=7)
    values[136:144, 8:16, 8:16] = 2.5  # aligned to the leaves: a tile, in the region from i = 128
    values[values == 0] = -1000.0
    path = str(tmp_path / "tiles.vdb")
    pn.Grid.from_dense(values, affine_matrix(), background=-1000.0).write_vdb(path)
    grid, stream = pn.read_vdb(path), pn.stream_vdb(path, batch_bytes=1)
    assert stream.leaf_count < grid.block_count  # the tile is there
    for k in (1, 4, 5):
        np.testing.assert_array_equal(stream.level(k, reduction).to_dense(-1000.0),
                                      grid.level(k, reduction).to_dense(-1000.0))


def test_streams_of_some_batches_sum_to_the_whole_batch_by_batch(files):
    """GridStream.with_batches (for renders split over processes, pcvr_addon/batch/split_xray.py): each batch
    rendered alone, added in batch order as float32, is the streamed render bit for bit; a coarse level is never
    taken for some batches only."""
    path = str(files / "field.vdb")
    stream = pn.stream_vdb(path, batch_bytes=2 * MiB)
    cam = field_view(stream, "orthographic")
    limit = 16 * MiB  # the batches' 2 MiB and the image's buffers
    count = stream.batch_count(2 * MiB)
    assert count == 3 and stream.batch_count(1) == 7 and stream.batch_count(1 << 40) == 1  # as render_streamed
    # The paper's passband: a whole render of a field >= 0 clears the compensation's ringing below zero, which
    # shares of it do not (their sum is the whole render before it: test_xray_nonnegative.py).
    whole = pn.render_xray(stream, cam, memory_limit=limit, level=0, passband="paper")
    parts = [pn.render_xray(stream.with_batches([b], 2 * MiB), cam, memory_limit=limit, level=0, passband="paper")
             for b in range(count)]
    total = parts[0].copy()
    for part in parts[1:]:
        total += part
    assert np.array_equal(total, whole)
    assert stream.with_batches([2, 0, 2], 2 * MiB).only_batches == [0, 2]
    assert stream.with_batches([1], 2 * MiB).value_range == pn.read_vdb(path).value_range  # the grid's
    stats = {}
    pn.render_xray(stream.with_batches([1], 2 * MiB), cam, memory_limit=limit, level=2, stats=stats)
    assert (stats["batches"], stats["level"]) == (1, 2)  # level 2 of one batch, not the stream's kept level
    with pytest.raises(ValueError, match=r"batches must be some of 0 to 2 \(3 batches"):
        stream.with_batches([3], 2 * MiB)
    with pytest.raises(ValueError, match="chosen at 2097152 bytes a batch"):
        pn.render_xray(stream.with_batches([0], 2 * MiB), cam, memory_limit=2 * MiB)
