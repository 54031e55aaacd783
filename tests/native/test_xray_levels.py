"""Levels of detail (Grid.level, render_xray(level=...), src/view/level_of_detail.h): each level halves the
resolution by averaging 2 x 2 x 2 voxels, lines up with the others, holds the same mass, and the
automatic choice keeps zoomed-out images within 0.5% of the pixel means while visiting far fewer voxels.
Zoomed out orthographic views at level 0 are rendered supersampled (a sub-pixel per voxel) and box-averaged.
"""

from __future__ import annotations

import numpy as np
import pytest

import pcvr_native as pn

from conftest import frame_ortho, rel_rmse, render
from pcvr_native import phantoms

from conftest import frame_perspective, volume_mass
from test_xray_minification import OFFSET, VIEW, blobs, one_pixel_view, reference_factor
from xray_helpers import pixel_means


@pytest.fixture(scope="module")
def cubic():
    return blobs()


def test_a_level_averages_and_lines_up():
    """Level 1 of a 4^3 ramp: voxel I is the mean of voxels 2I and 2I + 1, and sits at their centre."""
    values = np.arange(64, dtype=np.float32).reshape(4, 4, 4) + 1.0
    xf = np.diag([0.5, 0.75, 2.0, 1.0])
    xf[:3, 3] = (10.0, -3.0, 1.0)
    coarse = pn.Grid.from_dense(values, xf).level(1)
    expected = values.reshape(2, 2, 2, 2, 2, 2).mean(axis=(1, 3, 5))
    np.testing.assert_allclose(coarse.to_dense(), expected, rtol=1e-6)
    # Index 0 of level 1 sits at index 0.5 of level 0; one index unit is two.
    np.testing.assert_allclose(np.asarray(coarse.index_to_world), xf @ np.array(
        [[2, 0, 0, 0.5], [0, 2, 0, 0.5], [0, 0, 2, 0.5], [0, 0, 0, 1]]))


def test_a_constant_volume_looks_the_same_at_every_level():
    """A constant 64^3 cube at magnification 1/4: at every level the line integrals through its inside
    agree (edges blur differently: the coarse kernels reach further). Levels 0 and 1 are integrated over
    pixels and give the cube's depth to 1e-7; level 3's voxels span 2 pixels and are sampled, with the
    kernel's ripple over the lattice (measured 1.1e-3, the gauss1.4 footprints' 2 exp(-2 pi^2 0.35)
    = 2e-3 at worst)."""
    values = np.ones((64, 64, 64), dtype=np.float32)
    grid = pn.Grid.from_dense(values, np.eye(4))
    cam = frame_ortho((values, np.eye(4)), 1 / 4, direction=(0.0, 0.0, -1.0), offset=OFFSET)
    images = [render(grid, cam, "pcvr", level=k) for k in range(4)]
    inside = (slice(cam.height // 2 - 3, cam.height // 2 + 3), slice(cam.width // 2 - 3, cam.width // 2 + 3))
    for k, img in enumerate(images[1:], 1):
        np.testing.assert_allclose(img[inside], images[0][inside], rtol=2e-3, err_msg=f"level {k}")


@pytest.mark.parametrize("level", [1, 2, 3])
def test_every_level_holds_the_same_mass(cubic, level):
    ph, grid = cubic
    cam = frame_ortho(ph, 1 / 8, direction=VIEW, offset=OFFSET)
    fine = render(grid, cam, "pcvr", level=0).sum()
    assert render(grid, cam, "pcvr", level=level).sum() == pytest.approx(fine, rel=1e-4)


# Measured: 1/128 picks level 2 (1,669 voxels instead of 100,553) at 0.03% from the pixel means, 1/64
# level 1 (12,870) at 0.08%; 1/32 and closer take level 0 (level 1 there was 0.65% off: see
# src/view/level_of_detail.h).
@pytest.mark.parametrize("magnification, level", [(1 / 128, 2), (1 / 64, 1), (1 / 32, 0)])
def test_automatic_levels_stay_within_half_a_percent(cubic, magnification, level):
    ph, grid = cubic
    cam = frame_ortho(ph, magnification, direction=VIEW, offset=OFFSET)
    stats = {}
    img = render(grid, cam, "pcvr", stats=stats)
    assert stats["level"] == level
    # A coarse voxel is active where any of its 8 is: the blobs' ragged edge adds 2-6%.
    assert stats["voxels"] <= 1.1 * grid.active_voxel_count / 8 ** level
    assert rel_rmse(img, pixel_means(grid, cam, reference_factor(magnification))) < 5e-3


def test_a_coarse_level_costs_about_its_pixels(cubic):
    """At magnification 1/8 level 2 visits 1,669 voxels for an image of 255 pixels whose volume is
    6 pixels deep (level 0: 100,553): 1.1 times the image's pixels times its depth in pixels, where an
    X-ray has to add up every pixel's column. Its price is accuracy:
    4.96% from the pixel means where level 0 is 0.16% off (levels resample the volume; the 48^3 blobs'
    smallest is 3 voxels wide), so 6% here, and the automatic choice does not go there."""
    ph, grid = cubic
    cam = frame_ortho(ph, 1 / 8, direction=VIEW, offset=OFFSET)
    stats = {}
    img = render(grid, cam, "pcvr", level=2, stats=stats)
    depth_pixels = 48 / 8
    assert stats["level"] == 2 and stats["voxels"] <= 2 * cam.width * cam.height * depth_pixels
    assert rel_rmse(img, pixel_means(grid, cam, reference_factor(1 / 8))) < 0.06


@pytest.mark.parametrize("level", [-1, "fast", 1.5])
def test_bad_levels_are_refused(cubic, level):
    ph, grid = cubic
    with pytest.raises(ValueError, match="level"):
        render(grid, frame_ortho(ph, 1 / 8), "pcvr", level=level)


@pytest.fixture(scope="module")
def ct():
    ph = phantoms.ct_phantom(64)
    return ph, ph.grid()


# Supersampled zoomed-out views. The reference here has 3 x reference_factor sub-pixels a pixel edge: at
# reference_factor itself its samples would be the supersampled render's (one per voxel) and share their
# error (that reference is 0.12% off a finer one at 1/8). Measured (relative RMSE, blobs / CT phantom 64^3):
#   1/8: 0.142 / 0.141%   1/16: 0.100 / 0.054%   1/32: 0.076 / 0.022%   (sub-pixels 8, 16, 32)
# against 0.018 / 0.014, 0.011 / 0.006, 0.010 / 0.003% when every voxel is integrated over the pixels
# (level=0, as before), at 5 to 8 times the time on 128^3 blobs. The error is the midpoint rule's: a sampled
# line integral per voxel, averaged; it falls as the sub-pixels per pixel grow. Bound: 0.2% (the largest
# measured, 0.142%, and margin), within the 0.5%.
@pytest.mark.parametrize("volume", ["blobs", "ct"])
@pytest.mark.parametrize("magnification, sub_pixels", [(1 / 8, 8), (1 / 16, 16), (1 / 32, 32)])
def test_zoomed_out_views_are_supersampled_near_the_pixel_means(cubic, ct, volume, magnification, sub_pixels):
    ph, grid = cubic if volume == "blobs" else ct
    cam = frame_ortho(ph, magnification, direction=VIEW, offset=OFFSET)
    stats = {}
    img = render(grid, cam, "pcvr", stats=stats)
    assert (stats["level"], stats["supersampling"]) == (0, sub_pixels)
    assert stats["magnification"] == pytest.approx(magnification, rel=1e-6)  # of the pixels, not the sub-pixels
    assert rel_rmse(img, pixel_means(grid, cam, 3 * reference_factor(magnification))) < 2e-3


# Anisotropic voxels (1 : 1.6 : 0.7, and sheared) supersampled, measured as above: scaled 0.062 / 0.036%,
# sheared 0.094 / 0.073% at 1/16 / 1/32 (integrated: 0.159 / 0.056%, 0.020 / 0.024%). Bound as above.
@pytest.mark.parametrize("linear", ["scaled", "sheared"])
@pytest.mark.parametrize("magnification", [1 / 16, 1 / 32])
def test_anisotropic_voxels_are_supersampled_near_the_pixel_means(linear, magnification):
    ph, grid = blobs(linear)
    cam = frame_ortho(ph, magnification, direction=VIEW, offset=OFFSET)
    stats = {}
    img = render(grid, cam, "pcvr", stats=stats)
    assert stats["supersampling"] == round(1 / magnification)
    assert rel_rmse(img, pixel_means(grid, cam, 3 * reference_factor(magnification))) < 2e-3


# Measured: the 12^3 to 24^3 CT phantoms in one pixel render at 28 to 51 sub-pixels a side, 0.005 to 0.022%
# from the mean (integrated per pixel: 1e-7); the sampled footprints' ripple over the sub-pixels. Bound 0.1%.
@pytest.mark.parametrize("n", [12, 16])
def test_a_one_pixel_image_is_supersampled_and_the_mean_of_the_view(n):
    ph = phantoms.ct_phantom(n)
    cam, area = one_pixel_view(ph.values, ph.index_to_world)
    stats = {}
    img = render(ph.grid(), cam, "pcvr", stats=stats)
    assert stats["level"] == 0 and stats["supersampling"] >= 28
    assert img[0, 0] == pytest.approx(volume_mass(ph.values, ph.index_to_world) / area, rel=1e-3)


@pytest.mark.parametrize("why, kwargs", [
    ("a voxel is 0.8 pixel", dict(magnification=0.8)),
    ("perspective", dict(magnification=1 / 16, perspective=True)),
    ("a coarse level", dict(magnification=1 / 64)),
    ("explicit level", dict(magnification=1 / 16, level=0)),
    ("sampled pixels", dict(magnification=1 / 16, antialias=False)),
    ("bilinear spreading", dict(magnification=1 / 16, method="bilinear_spread"))])
def test_where_views_are_not_supersampled(cubic, why, kwargs):
    """Supersampling is for zoomed-out orthographic views of level 0 chosen automatically: the views
    above render as before."""
    ph, grid = cubic
    m = kwargs.pop("magnification")
    frame = frame_perspective if kwargs.pop("perspective", False) else frame_ortho
    stats = {}
    method = kwargs.pop("method", "pcvr")
    render(grid, frame(ph, m, direction=VIEW), method, stats=stats, **kwargs)
    assert stats["supersampling"] == 1, why


def test_without_memory_for_the_sub_pixels_the_pixels_are_integrated(cubic):
    """A memory_limit that holds the image but not its 16 x 16 sub-pixels (at 1/16: about 1 MB against
    6 KB) renders as before rather than failing."""
    ph, grid = cubic
    cam = frame_ortho(ph, 1 / 16, direction=VIEW, offset=OFFSET)
    supersampled, integrated, limited = {}, {}, {}
    render(grid, cam, "pcvr", stats=supersampled)
    expected = render(grid, cam, "pcvr", level=0, stats=integrated)
    limit = (supersampled["memory_bytes"] + integrated["memory_bytes"]) // 2
    img = render(grid, cam, "pcvr", memory_limit=limit, stats=limited)
    assert supersampled["supersampling"] == 16 and limited["supersampling"] == 1
    np.testing.assert_array_equal(img, expected)


# Half and a quarter of a pixel per voxel, the default (compensated) passband, against the analytic pixel means
# of the volume's own Gaussians (their line integrals averaged over 16 x 16 sub-pixels): measured supersampled
# 0.36% and 0.28% (2 and 4 sub-pixels), integrated per pixel 0.13% and 0.29%, the paper's pair integrated 1.26%
# and 1.15% (128^3 blobs of sigma 1.5 to 5). Bound: the 0.5%. One core: 13.5 ms supersampled against
# 110 ms integrated, magnification 1 13.9 ms (docs: level_of_detail.h).
@pytest.mark.parametrize("magnification, sub_pixels", [(1 / 2, 2), (1 / 4, 4)])
def test_half_and_quarter_pixel_voxels_are_supersampled_near_the_truth(magnification, sub_pixels):
    rng = np.random.default_rng(7)
    blobs128 = [(tuple(rng.uniform(20, 108, 3)), float(rng.uniform(1.5, 5)), 1.0) for _ in range(60)]
    ph = phantoms.gaussian_blobs(128, blobs128)
    cam = frame_ortho(ph, magnification, direction=VIEW, offset=OFFSET)
    k = 16
    fine = phantoms.gaussian_blobs_xray(blobs128, (cam.world_to_camera, cam.projection, cam.width * k, cam.height * k),
                                        ph.index_to_world, kernel_variance=0.0)
    truth = fine.reshape(cam.height, k, cam.width, k).mean(axis=(1, 3))
    stats = {}
    img = pn.render_xray(ph.grid(), cam.camera(), stats=stats)
    assert stats["supersampling"] == sub_pixels
    assert rel_rmse(img, truth) < 5e-3
