"""Shaded and MIP renders of a GridStream (issue 40): the volume in bricks read one at a time, each with the margin
its kernels reach, rendered front to back in visibility order into one image (each brick owns the samples in its
box and continues the colour, opacity or maximum the bricks before it left), equal to the grid read whole.

The grid read whole is pn.read_vdb of the same file: a grid built in memory by from_dense holds its voxels in
another order, and its sheets sum splats in that order (orthographic shaded renders of the two measured up to
2.1e-3 apart at 5 of 37,000 pixels, where a gradient near zero turns the shading; RMS 4.5e-6).
"""

from __future__ import annotations

import numpy as np
import pytest

import pcvr_native as pn
from pcvr_native import phantoms

from xray_helpers import LINEAR_PARTS, frame_ortho, frame_perspective

SUN = pn.Light.sun(direction=(-0.5, -0.2, -0.8))
TF = pn.TransferFunction(density=[0.0, 0.15, 0.3, 0.9, 1.0],
                         rgba=[[0, 0, 0, 0], [0.9, 0.5, 0.4, 0.05], [0.9, 0.6, 0.5, 0.1], [1, 1, 1, 0.6], [1, 1, 1, 0.95]])
# Two threads: their tile buffers count against the memory limit (2 MB each here, more for perspective views,
# whose strides each keep a ring of sheets).
THREADS = 2


def least_limit(function, stream, cam, *args, **kwargs):
    """The least memory_limit that a render of `stream` takes (bricks of 16^3 voxels), as its refusal names it."""
    with pytest.raises(ValueError, match="raise memory_limit to at least") as refused:
        function(stream, cam, *args, memory_limit=1, threads=THREADS, **kwargs)
    return int(str(refused.value).split("at least ")[1].split(" ")[0])


def limit_for(function, stream, cam, *args, **kwargs):
    """50 kB above the least: 8 (MIP) to 64 (shaded) bricks over the 64^3 phantom, measured; 200 kB above, shaded
    also takes 8."""
    return least_limit(function, stream, cam, *args, **kwargs) + 50_000


@pytest.fixture(scope="module")
def ct_file(tmp_path_factory):
    """The 64^3 CT phantom on a sheared lattice (bricks are cubes of index space, not of the world)."""
    ph = phantoms.ct_phantom(64)
    xf = np.array(ph.index_to_world, dtype=np.float64)
    xf[:3, :3] = xf[:3, :3] @ LINEAR_PARTS["sheared"]
    path = tmp_path_factory.mktemp("bricks") / "ct.vdb"
    pn.Grid.from_dense(ph.values, xf).write_vdb(str(path))
    return str(path)


def camera(grid, projection, direction=(0.3, -0.5, -0.8), **kwargs):
    frame = frame_ortho if projection == "orthographic" else frame_perspective
    return frame(grid, 1.5, direction=direction, **kwargs).camera()


def bricked(function, path, cam, *args, **kwargs):
    stats = {}
    stream = pn.stream_vdb(path)
    limit = limit_for(function, stream, cam, *args, **kwargs)
    image = function(stream, cam, *args, memory_limit=limit, threads=THREADS, stats=stats, **kwargs)
    assert stats["batches"] > 1 and 0 < stats["memory_bytes"] <= limit
    return image, stats


@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
@pytest.mark.parametrize("options", [
    {}, {"opacity_cutoff": 1.0}, {"return_depth": True}, {"clip_planes": [(0.3, 0.2, 1.0, 0.05)]},
    {"method": "regular"}, {"classification": "preintegrated"}])
def test_splatted_bricks_make_the_grid_read_whole(ct_file, projection, options):
    """Sheets splatted: the same samples from the same splats composited in the same order, bit for bit (measured:
    0 difference with every option here, orthographic and perspective)."""
    grid = pn.read_vdb(ct_file)
    cam = camera(grid, projection)
    options = {"sheet_fill": "splat", **options}
    whole = pn.render_shaded(grid, cam, TF, lights=[SUN], **options)
    image, stats = bricked(pn.render_shaded, ct_file, cam, TF, lights=[SUN], **options)
    if options.get("return_depth"):
        np.testing.assert_array_equal(image[1], whole[1])
        image, whole = image[0], whole[0]
    assert whole[..., 3].max() > 0.9  # the bricks occlude one another
    np.testing.assert_allclose(image, whole, rtol=0, atol=1e-6)


def test_gradient_opacity_survives_the_brick_faces(ct_file):
    tf = pn.TransferFunction(density=TF.density, rgba=TF.rgba, gradient=[0.0, 5.0], gradient_opacity=[0.1, 1.0])
    grid = pn.read_vdb(ct_file)
    cam = camera(grid, "orthographic")
    image, _ = bricked(pn.render_shaded, ct_file, cam, tf, lights=[SUN], sheet_fill="splat")
    np.testing.assert_allclose(image, pn.render_shaded(grid, cam, tf, lights=[SUN], sheet_fill="splat"), rtol=0, atol=1e-6)


@pytest.mark.parametrize("projection, direction, distance", [
    ("orthographic", (0.3, -0.5, -0.8), 3.0), ("perspective", (0.3, -0.5, -0.8), 3.0),
    ("perspective", (0.0, 0.1, -1.0), 1.3), ("perspective", (-0.7, 0.6, 0.2), 2.0)])
def test_sampled_bricks_make_the_grid_read_whole(ct_file, projection, direction, distance):
    """Sheets sampled from a prefiltered lattice (the default here): each brick's lattice starts at its own
    corner, so a sample's lattice coordinates round differently, and where a gradient is near zero the shading
    turns on it. Measured over these views (the eye beside the volume or level with its middle bricks, whose order
    runs from the eye's brick outwards): RMS 2.2e-5 to 9.8e-5, the largest difference 2.6e-3 to 1.1e-2 at 7 to 49
    pixels of 22,000 to 50,000; unlit, at most 4.6e-6. Bricks composited in a wrong order differ by 0.66 to 0.70
    (test_shares_of_the_bricks_composite_to_the_whole_image)."""
    grid = pn.read_vdb(ct_file)
    kwargs = {"distance": distance} if projection == "perspective" else {}
    cam = camera(grid, projection, direction, **kwargs)
    whole = pn.render_shaded(grid, cam, TF, lights=[SUN])
    image, stats = bricked(pn.render_shaded, ct_file, cam, TF, lights=[SUN])
    assert stats["grids_sampled"] == 1
    difference = np.abs(image - whole).max(axis=2)
    assert np.sqrt(np.mean((image - whole) ** 2)) < 3e-4
    assert np.mean(difference > 1e-4) < 0.005 and difference.max() < 0.03
    unlit = pn.Shading(lit=False)
    image, _ = bricked(pn.render_shaded, ct_file, cam, TF, shading=unlit)
    np.testing.assert_allclose(image, pn.render_shaded(grid, cam, TF, shading=unlit), rtol=0, atol=1e-5)


@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
def test_bricked_mip_is_the_grid_read_whole(ct_file, projection):
    grid = pn.read_vdb(ct_file)
    cam = camera(grid, projection)
    image, _ = bricked(pn.render_mip, ct_file, cam)
    np.testing.assert_allclose(image, pn.render_mip(grid, cam), rtol=0, atol=1e-6)


def over(front, back):
    """Premultiplied RGBA `front` over `back`."""
    return front + (1.0 - front[..., 3:]) * back


@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
def test_shares_of_the_bricks_composite_to_the_whole_image(ct_file, projection):
    """brick_share=(k, n): each share's image alone, composited front to back in k's order (over; MIP: the
    maximum), as pcvr_addon.batch does over workers. With opacity_cutoff 1 only rounding parts them (measured
    6e-7); with the default 0.99 a share does not know the opacity in front of it and goes on where the
    whole stopped: at most the 1% left behind the cutoff (measured 9.4e-3). Composited back to front they
    differ by 0.66 to 0.70."""
    stream = pn.stream_vdb(ct_file)
    cam = camera(stream, projection)
    limit = limit_for(pn.render_shaded, stream, cam, TF, lights=[SUN])
    for cutoff, tolerance in [(1.0, 1e-5), (0.99, 0.011)]:
        whole = pn.render_shaded(stream, cam, TF, lights=[SUN], memory_limit=limit, threads=THREADS, opacity_cutoff=cutoff)
        parts = [pn.render_shaded(stream, cam, TF, lights=[SUN], memory_limit=limit, threads=THREADS, opacity_cutoff=cutoff,
                                  brick_share=(k, 3)) for k in range(3)]
        np.testing.assert_allclose(over(over(parts[0], parts[1]), parts[2]), whole, rtol=0, atol=tolerance)
        assert np.abs(over(over(parts[2], parts[1]), parts[0]) - whole).max() > 0.3
    limit = limit_for(pn.render_mip, stream, cam)
    mips = [pn.render_mip(stream, cam, memory_limit=limit, threads=THREADS, brick_share=(k, 3)) for k in range(3)]
    np.testing.assert_array_equal(np.maximum.reduce(mips), pn.render_mip(stream, cam, memory_limit=limit, threads=THREADS))


def test_what_needs_the_whole_grid_is_refused_by_name(ct_file):
    stream = pn.stream_vdb(ct_file)
    cam = camera(stream, "orthographic")
    for kwargs, cause in [({"shadows": True}, "shadows"), ({"method": "raycast"}, "raycast"),
                          ({"shading": pn.Shading(ambient_occlusion=True)}, "ambient occlusion")]:
        with pytest.raises(ValueError, match=f"'density' of '.*ct.vdb'.*{cause}"):
            pn.render_shaded(stream, cam, TF, lights=[SUN], **kwargs)
    with pytest.raises(ValueError, match="shadows"):
        pn.render_shaded(stream, cam, TF, lights=[pn.Light.sun(direction=(0, 0, -1), shadow=True)])
    with pytest.raises(ValueError, match="for a GridStream"):
        pn.render_mip(pn.read_vdb(ct_file), cam, memory_limit=10_000_000)
    with pytest.raises(ValueError, match="brick_share"):
        pn.render_mip(stream, cam, brick_share=(3, 3))
    with pytest.raises(ValueError, match="with_batches.*brick_share"):
        pn.render_mip(stream.with_batches([0], 1 << 20), cam)


def test_a_coarse_level_of_a_stream_renders_whole(ct_file):
    """level=k renders the stream's level k (made from the file a batch at a time), as the grid's level k."""
    stream = pn.stream_vdb(ct_file)
    cam = camera(stream, "orthographic")
    stats = {}
    image = pn.render_shaded(stream, cam, TF, lights=[SUN], level=1, stats=stats)
    assert stats["level"] == 1 and stats["batches"] == 0
    whole = pn.render_shaded(pn.read_vdb(ct_file), cam, TF, lights=[SUN], level=1)
    np.testing.assert_allclose(image, whole, rtol=0, atol=1e-5)


@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
@pytest.mark.parametrize("mode", ["shaded", "mip"])
def test_the_working_set_counted_fits_the_memory_limit(ct_file, projection, mode):
    """stats['memory_bytes']: the most the render holds at once as counted (the image, the threads' buffers, one
    brick's values and what is built over them, and 4 MiB for what the count leaves out): within the limit for
    limits from the least to one that holds the phantom in one brick, the bricks fewer as it grows. On the bench's
    CT the measured peak stayed under the count (docs/rendering-at-scale.md)."""
    stream = pn.stream_vdb(ct_file)
    cam = camera(stream, projection)
    args = (TF,) if mode == "shaded" else ()
    function = pn.render_shaded if mode == "shaded" else pn.render_mip
    kwargs = {"lights": [SUN]} if mode == "shaded" else {}
    least = least_limit(function, stream, cam, *args, **kwargs)
    bricks = []
    for limit in [least, least + 50_000, least + 100_000, least + 400_000, least + 20_000_000]:
        stats = {}
        function(stream, cam, *args, memory_limit=limit, threads=THREADS, stats=stats, **kwargs)
        assert 0 < stats["memory_bytes"] <= limit
        bricks.append(stats["batches"])
    assert bricks == sorted(bricks, reverse=True) and bricks[1] > 1 and bricks[-1] == 1


def test_a_limit_below_the_working_set_is_refused_with_what_it_must_hold(ct_file):
    stream = pn.stream_vdb(ct_file)
    cam = camera(stream, "orthographic")
    for function, args in [(pn.render_shaded, (TF,)), (pn.render_mip, ())]:
        with pytest.raises(ValueError, match=r"'density' of '.*ct.vdb': memory_limit of 5000000 bytes is below what one brick's "
                                             r"render holds: the image \(\d+ bytes\), the threads' tile buffers .* raise "
                                             r"memory_limit to at least \d+ bytes"):
            function(stream, cam, *args, memory_limit=5_000_000, threads=THREADS)


def test_brick_bytes_caps_a_bricks_values_without_a_memory_limit(ct_file):
    """Blender's Stream Above: bricks of at most brick_bytes of values (whole 8^3 leaves with the margin's), whatever
    the rest of the render holds; too few for a brick of 16^3 voxels and its margin is refused with the least."""
    stream = pn.stream_vdb(ct_file)
    cam = camera(stream, "orthographic")
    stats = {}
    image = pn.render_mip(stream, cam, brick_bytes=300_000, stats=stats)
    assert stats["batches"] > 1
    np.testing.assert_array_equal(image, pn.render_mip(stream, cam))
    with pytest.raises(ValueError, match=r"bricks of at most 100000 bytes of values \(brick_bytes.*allow at least \d+"):
        pn.render_mip(stream, cam, brick_bytes=100_000)
