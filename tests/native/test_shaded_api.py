"""render_shaded and render_mip as a caller meets them: arguments, errors, several volumes, progress,
cancellation, and output that stays finite whatever the data."""

from __future__ import annotations

import time

import numpy as np
import pytest

import pcvr_native as pn
from pcvr_native import phantoms

from conftest import frame_ortho
from shaded_scenes import SUN, blob_volume, bone_tf, camera, ct_volume


@pytest.fixture(scope="module")
def blobs():
    grid = blob_volume(24)
    return grid, camera(grid, "ortho", 3.0)


def test_result_is_premultiplied_rgba_with_alpha_zero_where_nothing_is_hit(blobs):
    grid, cam = blobs
    image = pn.render_shaded(grid, cam, bone_tf(), lights=[SUN])
    assert image.dtype == np.float32 and image.shape == (cam.height, cam.width, 4)
    assert image[0, 0].tolist() == [0, 0, 0, 0]
    alpha = image[..., 3]
    assert alpha.max() > 0.9 and (alpha >= 0).all() and (alpha <= 1).all()
    # Premultiplied: no channel exceeds alpha times the brightest lit colour (1 * (0.1 + 0.9) + 0.2).
    assert (image[..., :3] <= 1.2 * alpha[..., None] + 1e-6).all()


def test_one_transfer_function_serves_every_grid_or_one_each(blobs):
    grid, cam = blobs
    one = pn.render_shaded([grid, grid], cam, bone_tf(), lights=[SUN])
    each = pn.render_shaded([grid, grid], cam, [bone_tf(), bone_tf()], lights=[SUN])
    assert np.array_equal(one, each)
    with pytest.raises(ValueError, match="one per grid"):
        pn.render_shaded([grid, grid], cam, [bone_tf()], lights=[SUN])


def test_each_grid_may_have_its_own_material(two_cubes_apart):
    """Two cubes side by side, one matte and one shiny: each looks as it does alone with its material."""
    grids, cam = two_cubes_apart
    matte, shiny = pn.Shading(specular=0.0), pn.Shading(diffuse=0.3, specular=1.0, shininess=40.0)
    tf = pn.TransferFunction(density=[0.0, 1.0], rgba=[[1, 1, 1, 0], [0.6, 0.6, 0.6, 1]])
    both = pn.render_shaded(grids, cam, tf, lights=[SUN], shading=[matte, shiny])
    alone = [pn.render_shaded([g], cam, tf, lights=[SUN], shading=s) for g, s in zip(grids, (matte, shiny))]
    assert np.abs(both - alone[0] - alone[1]).max() < 1e-6  # apart: the images add up
    assert np.abs(alone[0] - pn.render_shaded([grids[0]], cam, tf, lights=[SUN], shading=shiny)).max() > 0.05
    assert np.array_equal(pn.render_shaded(grids, cam, tf, lights=[SUN], shading=[shiny, shiny]),
                          pn.render_shaded(grids, cam, tf, lights=[SUN], shading=shiny))
    with pytest.raises(ValueError, match="one per grid"):
        pn.render_shaded(grids, cam, tf, lights=[SUN], shading=[matte])
    with pytest.raises(ValueError, match="grid 'density'.*Shading"):
        bad = pn.Shading()
        bad.specular = -1.0
        pn.render_shaded(grids, cam, tf, lights=[SUN], shading=[matte, bad])


@pytest.fixture(scope="module")
def two_cubes_apart():
    values = np.zeros((12, 12, 12), np.float32)
    values[2:10, 2:10, 2:10] = 1.0
    left, right = np.eye(4), np.eye(4)
    left[:3, 3] = (-10.0, 0.0, 0.0)
    right[:3, 3] = (10.0, 0.0, 0.0)
    grids = [pn.Grid.from_dense(values, left), pn.Grid.from_dense(values, right)]
    both = np.eye(4)
    both[:3, 3] = (-10.0, 0.0, 0.0)
    cam = frame_ortho((np.ones((32, 12, 12), np.float32), both), 3.0, direction=(0.3, 0.4, -1.0)).camera()
    return grids, cam


def test_density_scale_multiplies_values_before_classification(blobs):
    grid, cam = blobs
    scaled = pn.render_shaded(grid, cam, bone_tf(), lights=[SUN], density_scale=2.0, opacity_cutoff=1.0)
    values = grid.to_dense()
    lo = np.asarray(grid.index_bbox[0])
    xf = np.asarray(grid.index_to_world).copy()
    xf[:3, 3] += xf[:3, :3] @ lo
    doubled = pn.Grid.from_dense(2.0 * values, xf)
    direct = pn.render_shaded(doubled, cam, bone_tf(), lights=[SUN], opacity_cutoff=1.0)
    assert np.abs(scaled - direct).max() < 1e-5


def two_cubes(front_colour, back_colour):
    """Two opaque cubes 40 world units apart along the view (-z), overlapping on the image."""
    values = np.zeros((10, 10, 10), np.float32)
    values[2:8, 2:8, 2:8] = 1.0
    near = np.eye(4)
    near[:3, 3] = (0.0, 0.0, 20.0)
    far = np.eye(4)
    far[:3, 3] = (2.0, 1.0, -20.0)
    grids = [pn.Grid.from_dense(values, near), pn.Grid.from_dense(values, far)]
    tfs = [pn.TransferFunction(density=[0.0, 0.5, 1.0], rgba=[[*c, 0.0], [*c, 0.9], [*c, 1.0]]) for c in (front_colour, back_colour)]
    return grids, tfs


@pytest.mark.parametrize("order", [(0, 1), (1, 0)])
def test_the_nearer_of_two_volumes_hides_the_other_in_either_order(order):
    grids, tfs = two_cubes((1.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    cam = frame_ortho((np.ones((10, 10, 50)), np.eye(4)), 4.0, direction=(0.0, 0.0, -1.0)).camera()
    flat = dict(ambient=(1, 1, 1), shading=pn.Shading(ambient=1.0, diffuse=0.0, specular=0.0))
    alone = [pn.render_shaded(g, cam, tf, **flat)[..., 3] for g, tf in zip(grids, tfs)]
    overlap = (alone[0] > 0.98) & (alone[1] > 0.98)
    assert overlap.sum() > 50
    image = pn.render_shaded([grids[i] for i in order], cam, [tfs[i] for i in order], **flat)
    # Where both cubes are opaque, only the near (red) one shows, whichever was listed first.
    assert (image[overlap, 0] > 0.98).all() and (image[overlap, 2] < 0.02).all()
    # Where only the far one is, it shows.
    far_only = (alone[1] > 0.98) & (alone[0] == 0)
    assert far_only.sum() > 20 and (image[far_only, 2] > 0.98).all()


def test_errors_name_the_problem(blobs):
    grid, cam = blobs
    with pytest.raises(ValueError, match="unknown method 'exact'"):
        pn.render_shaded(grid, cam, bone_tf(), method="exact")
    with pytest.raises(ValueError, match="increase"):
        pn.TransferFunction(density=[0.0, 0.5, 0.5], rgba=[[0, 0, 0, 0]] * 3)
    with pytest.raises(ValueError, match="2 densities but 1"):
        pn.TransferFunction(density=[0.0, 1.0], rgba=[[0, 0, 0, 0]])
    with pytest.raises(ValueError, match=r"opacity must lie in \[0, 1\]"):
        pn.TransferFunction(density=[0.0], rgba=[[1, 1, 1, 1.5]])
    with pytest.raises(ValueError, match="sheet_spacing"):
        pn.render_shaded(grid, cam, bone_tf(), sheet_spacing=0.0)
    with pytest.raises(ValueError, match="sheet spacing too small"):
        pn.render_shaded(grid, cam, bone_tf(), sheet_spacing=1e-3)
    with pytest.raises(ValueError, match="opacity_cutoff"):
        pn.render_shaded(grid, cam, bone_tf(), opacity_cutoff=1.5)
    with pytest.raises(ValueError, match="pixel_step"):
        pn.render_shaded(grid, cam, bone_tf(), method="pcvr", pixel_step=2)
    with pytest.raises(ValueError, match="a sun needs a direction"):
        pn.Light.sun(direction=(0, 0, 0))
    with pytest.raises(ValueError, match="Shading"):
        pn.Shading(diffuse=-1.0)
    with pytest.raises(ValueError, match="unknown post filter"):
        pn.render_mip(grid, cam, post_filter="sinc")


def test_empty_grids_render_nothing():
    empty = pn.Grid.from_dense(np.zeros((4, 4, 4), np.float32), np.eye(4))
    cam = frame_ortho((np.ones((4, 4, 4)), np.eye(4)), 2.0).camera()
    assert not pn.render_shaded(empty, cam, bone_tf(), lights=[SUN]).any()
    assert not pn.render_mip(empty, cam).any()
    assert pn.render_shaded([], cam, bone_tf()).shape == (cam.height, cam.width, 4)


def test_output_is_finite_for_extreme_values():
    rng = np.random.default_rng(3)
    values = rng.uniform(-1.0, 1.0, (16, 16, 16)).astype(np.float32)
    values[3:6, 3:6, 3:6] = 1e30
    values[8, 8, 8] = -1e30
    values[10:12, 10:12, 10:12] = 1e-40  # denormals
    grid = pn.Grid.from_dense(values, np.eye(4))
    cam = frame_ortho((values, np.eye(4)), 3.0, direction=(0.2, 0.3, -1.0)).camera()
    steep = pn.TransferFunction(density=[-1e30, 0.0, 1e-6, 1e30], rgba=[[1, 1, 1, 1], [1, 0, 0, 0], [0, 1, 0, 1], [0, 0, 1, 1]])
    for method in ("regular", "pcvr", "bilinear_spread"):
        assert np.isfinite(pn.render_shaded(grid, cam, steep, lights=[SUN], method=method)).all()
        assert np.isfinite(pn.render_mip(grid, cam, method=method)).all()


def test_a_camera_inside_the_volume_renders_what_is_in_front():
    grid = ct_volume(32)
    xf = np.asarray(grid.index_to_world)
    centre = xf[:3, :3] @ np.array([15.5, 15.5, 15.5]) + xf[:3, 3]
    from pcvr_native.cameras import look_at, perspective
    cam = pn.Camera(look_at(centre, centre + np.array([0.0, 0.0, -1.0]), (0, 1, 0)), perspective(60.0, 1.0, 0.05, 10.0), 64, 64)
    # Measured: the ray caster's most opaque pixel 0.50, the splats' 0.69, sampled sheets' 0.48.
    for method, fill in (("regular", "splat"), ("pcvr", "splat"), ("pcvr", "sample")):
        image = pn.render_shaded(grid, cam, bone_tf(), lights=[SUN], method=method, sheet_fill=fill)
        assert np.isfinite(image).all() and image[..., 3].max() > 0.4


@pytest.fixture(scope="module")
def slow():
    """A render that takes a noticeable time on one thread (~0.5-1 s), and that time."""
    grid = ct_volume(96)
    cam = camera(grid, "persp", 3.0)
    kw = dict(lights=[SUN], threads=1, samples_per_sheet=4, opacity_cutoff=1.0)
    start = time.perf_counter()
    pn.render_shaded(grid, cam, bone_tf(), **kw)
    return grid, cam, kw, time.perf_counter() - start


def test_progress_rises_to_one(slow):
    grid, cam, kw, _ = slow
    seen = []
    pn.render_shaded(grid, cam, bone_tf(), progress=seen.append, **kw)
    assert seen[-1] == 1.0 and all(b >= a for a, b in zip(seen, seen[1:]))
    assert len([f for f in seen if 0.0 < f < 1.0]) >= 3


@pytest.mark.parametrize("mode", ["shaded", "mip", "raycast"])
def test_cancel_stops_a_render_quickly(slow, mode):
    grid, cam, kw, full = slow
    start = time.perf_counter()
    deadline = start + 0.1 * full
    cancel = lambda: time.perf_counter() > deadline  # noqa: E731
    with pytest.raises(pn.RenderCancelled):
        if mode == "shaded":
            pn.render_shaded(grid, cam, bone_tf(), cancel=cancel, **kw)
        elif mode == "mip":
            pn.render_mip(grid, cam, threads=1, sheet_spacing=0.1, cancel=cancel)
        else:
            pn.render_shaded(grid, cam, bone_tf(), method="raycast", lights=[SUN], threads=1, cancel=cancel)
    # Polled every ~20 ms; the render must stop long before it would have finished.
    assert time.perf_counter() - start < 0.5 * full + 0.1


@pytest.mark.parametrize("method", ["regular", "pcvr", "raycast"])
@pytest.mark.parametrize("projection", ["ortho", "persp"])
def test_depth_is_where_opacity_reaches_one_half(method, projection):
    """An opaque slab whose front face lies at a known depth: the depth pass finds that face within a
    voxel (the kernel softens the face over about a voxel, and samples are a sheet apart)."""
    values = np.zeros((16, 16, 16), np.float32)
    values[2:14, 2:14, 3:9] = 1.0  # k (world z) 3..8: the face nearest a camera looking down -z is z = 8
    grid = pn.Grid.from_dense(values, np.eye(4))
    cam = camera(grid, projection, 3.0, direction=(0.0, 0.0, -1.0))
    tf = pn.TransferFunction(density=[0.0, 1.0], rgba=[[1, 1, 1, 0], [1, 1, 1, 1]])
    kw = dict(sheet_spacing=0.1) if method == "raycast" else {}
    image, depth = pn.render_shaded(grid, cam, tf, method=method, return_depth=True, **kw)
    assert depth.shape == image.shape[:2] and depth.dtype == np.float32
    face = -(np.asarray(cam.world_to_camera) @ np.array([8.0, 8.0, 8.0, 1.0]))[2]  # depth of the face's centre
    centre = depth[depth.shape[0] // 2, depth.shape[1] // 2]
    assert abs(centre - face) <= 1.0
    assert np.isinf(depth[0, 0]) and image[0, 0, 3] == 0
    assert np.isfinite(depth[image[..., 3] >= 0.5]).all()
