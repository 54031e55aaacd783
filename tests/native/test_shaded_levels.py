"""Levels of detail in shaded rendering and MIP (render_shaded / render_mip `level=`, src/shaded/classify/shaded_levels.h).

Their levels count inactive voxels as the grid's background, which is what the sheets reconstruct towards
beyond the active voxels (the X-ray's levels count them as 0), shaded rendering's as means and MIP's as
maxima; the transfer function's default unit stays level 0's voxel spacing; a level visits about 1/8 of the
voxels of the one before; and zoomed out, where voxels are far smaller than pixels, a level's image stays near
level 0's pixel means.
"""

from __future__ import annotations

import numpy as np
import pytest

import pcvr_native as pn

from conftest import rel_rmse
from level_scenes import TRANSLUCENT, pixel_means, scattered_blobs
from shaded_scenes import AIR, SUN, TISSUE_AND_BONE, VIEW, camera, ct_volume, heads_in_air, psnr


def test_levels_average_or_take_the_largest_with_inactive_voxels_as_the_background():
    """Level 1 of a 4^3 grid in air: each voxel the mean of its 2^3 with inactive ones counting as -1000
    (render_shaded's levels) or as 0 (the X-ray's), or their largest with inactive ones counting as -1000
    (render_mip's); a 2^3 of air only stays inactive; the background is kept."""
    values = np.full((4, 4, 4), AIR, dtype=np.float32)
    values[0, 0, 0], values[1, 1, 0] = 600.0, -200.0   # two of the first 2^3
    values[2:, 2:, 2:] = -1200.0                         # all of the last, below the background
    values[3, 3, 3] = -1100.0
    grid = pn.Grid.from_dense(values, np.eye(4), background=AIR)
    shaded, xray, mip = (grid.level(1, reduction) for reduction in
                         ("mean_over_background", "mean_over_zero", "max_over_background"))
    assert shaded.background == xray.background == mip.background == AIR
    assert shaded.active_voxel_count == xray.active_voxel_count == mip.active_voxel_count == 2
    expected = np.full((2, 2, 2), np.nan)
    expected[1, 1, 1] = (7 * -1200.0 - 1100.0) / 8
    expected[0, 0, 0] = (600.0 - 200.0 + 6 * AIR) / 8
    np.testing.assert_allclose(shaded.to_dense(fill=np.nan), expected, rtol=1e-6)
    expected[0, 0, 0] = (600.0 - 200.0) / 8
    np.testing.assert_allclose(xray.to_dense(fill=np.nan), expected, rtol=1e-6)
    expected[0, 0, 0], expected[1, 1, 1] = 600.0, -1100.0   # the air around the first counts, not around the last
    np.testing.assert_allclose(mip.to_dense(fill=np.nan), expected, rtol=1e-6)
    for level in (shaded, mip):
        np.testing.assert_allclose(np.asarray(level.index_to_world), np.asarray(xray.index_to_world))
    # Level 2 is level 1's level: one voxel standing for the whole grid with its air.
    np.testing.assert_allclose(grid.level(2, "mean_over_background").to_dense(), [[[values.mean()]]], rtol=1e-6)
    np.testing.assert_allclose(grid.level(2, "max_over_background").to_dense(), [[[600.0]]])


def test_over_a_background_of_zero_both_means_are_the_same():
    values = np.random.default_rng(3).uniform(0.0, 1.0, (8, 8, 8)).astype(np.float32)
    values[values < 0.5] = 0.0
    grid = pn.Grid.from_dense(values, np.eye(4))
    np.testing.assert_array_equal(grid.level(1, "mean_over_background").to_dense(), grid.level(1).to_dense())


def test_a_reduction_must_be_named():
    with pytest.raises(ValueError, match="reduction"):
        pn.Grid.from_dense(np.ones((2, 2, 2), np.float32), np.eye(4)).level(1, "median")


# -------------------------------------------------------------------------------------------------
# Rendering from levels

@pytest.fixture(scope="module")
def heads():
    """A ball of soft tissue with a bone core in air, 48^3: air inactive (sparse) and air active (dense)."""
    return heads_in_air(48)


@pytest.mark.parametrize("level", [1, 2])
def test_inactive_air_renders_as_active_air_at_every_level(heads, level):
    """The dense head's levels hold air where the sparse head's have inactive voxels: both render alike only
    when those count as air. Measured 2.3e-6 and 3.2e-6 (shaded), 0.004 and 0.018 HU (MIP) at levels 1 and 2;
    the X-ray's levels of the sparse head, inactive voxels counting as 0, differ from the dense head's by 0.91 and
    0.99 in RGBA: their coarse rim, tissue averaged with 0 (5 to 40 HU, where air gives -870 to 40), draws a
    shell of soft tissue."""
    sparse, dense = heads
    cam = camera(sparse, "ortho", 1.0)
    shaded = [pn.render_shaded(g, cam, TISSUE_AND_BONE, lights=[SUN], level=level) for g in heads]
    assert shaded[0][..., 3].max() > 0.5
    assert np.abs(shaded[0] - shaded[1]).max() < 1e-4
    mip = [pn.render_mip(g, cam, level=level) for g in heads]
    assert mip[0].min() >= AIR and mip[0].max() > 600
    assert np.abs(mip[0] - mip[1]).max() < 0.1


def test_the_transfer_functions_unit_stays_level_0s_voxel():
    """Opacity is given per voxel spacing of the grid (unit_distance None): a level, whose voxels are twice as
    far apart, must not halve the extinction. Inside a constant cube every level shows the same opacity, 0.475
    (measured within 8e-5 and 2.3e-4 at levels 1 and 2; with level 1's own spacing as the unit, 0.28)."""
    values = np.full((32, 32, 32), 0.5, dtype=np.float32)
    grid = pn.Grid.from_dense(values, np.eye(4))
    tf = pn.TransferFunction(density=[0.0, 1.0], rgba=[[1, 1, 1, 0.0], [1, 1, 1, 0.04]])
    cam = camera(grid, "ortho", 1.0, direction=(0.0, 0.0, -1.0))
    alphas = [pn.render_shaded(grid, cam, tf, level=k)[..., 3] for k in range(3)]
    centre = (slice(cam.height // 2 - 2, cam.height // 2 + 2), slice(cam.width // 2 - 2, cam.width // 2 + 2))
    assert alphas[0][centre].min() > 0.2
    for k in (1, 2):
        np.testing.assert_allclose(alphas[k][centre], alphas[0][centre], atol=2e-3, err_msg=f"level {k}")


@pytest.fixture(scope="module")
def cloud():
    return scattered_blobs(64)


@pytest.mark.parametrize("level", [1, 2])
def test_mip_levels_keep_thin_bright_structures(level):
    """MIP draws from levels of maxima: the CT phantom's skull, one voxel thick at 64^3, keeps its brightest
    value at levels 1 and 2 (measured 0.928 and 0.945 against level 0's 0.927), where levels of means, shaded
    rendering's, lose a third and more of it (0.63 and 0.40); the image stays nearer level 0's (relative RMSE
    21% and 42% against 37% and 59%)."""
    grid = ct_volume(64)
    cam = camera(grid, "ortho", 1 / 2)
    level_0 = pn.render_mip(grid, cam)
    maxima = pn.render_mip(grid, cam, level=level)
    means = pn.render_mip(grid.level(level, "mean_over_background"), cam)
    assert maxima.max() == pytest.approx(level_0.max(), rel=0.05)
    assert means.max() < 0.7 * level_0.max()
    assert rel_rmse(maxima, level_0) < rel_rmse(means, level_0) - 0.1


@pytest.mark.parametrize("level", [1, 2])
def test_a_level_visits_an_eighth_of_the_voxels_of_the_one_before(cloud, level):
    """Every voxel splatted once (one tile, nothing culled or occluded; sheets splatted, not sampled): level k's
    are level 0's / 8^k, plus
    the coarse voxels that are active where any of their eight is (measured 1.007 and 1.018 times / 8^k here)."""
    cam = camera(cloud, "ortho", 1 / 2)
    counts = {}
    for k in (0, level):
        for name, render in (("shaded", lambda **kw: pn.render_shaded(cloud, cam, TRANSLUCENT, lights=[SUN], **kw)),
                             ("mip", lambda **kw: pn.render_mip(cloud, cam, **kw))):
            stats = {}
            render(level=k, cull_transparent=False, opacity_cutoff=1.0, sheet_fill="splat", stats=stats) if name == "shaded" else \
                render(level=k, stats=stats)
            assert stats["level"] == k and stats["tiles"] == 1
            counts[name, k] = stats["voxels"]
    assert counts["shaded", 0] == counts["mip", 0] == cloud.active_voxel_count
    for name in ("shaded", "mip"):
        assert counts[name, 0] / 8 ** level <= counts[name, level] <= 1.05 * counts[name, 0] / 8 ** level


# Measured on these blobs (tests/bench/shaded_levels.py --quick), PSNR of RGBA: level 1 at magnification
# 1/16 is 55.2 dB from level 0 (1.8% relative RMSE) and 31.8 dB from level 0's pixel means, as level 0 itself
# (31.8 dB: at 1/16 both sample the volume at the pixels' centres, and neither averages over a pixel); level 2,
# 44.2 and 32.9 dB. Thresholds: 3 dB below (other compilers' and CPUs' rounding move single pixels of these
# small images).
ZOOMED_OUT = {1: (52.0, 28.8), 2: (41.0, 29.9)}


@pytest.mark.parametrize("level", [1, 2])
def test_zoomed_out_a_level_looks_like_level_0(cloud, level):
    cam = camera(cloud, "ortho", 1 / 16, direction=VIEW)
    means = pixel_means(lambda camera: pn.render_shaded(cloud, camera, TRANSLUCENT, lights=[SUN]), cam)
    level_0 = pn.render_shaded(cloud, cam, TRANSLUCENT, lights=[SUN])
    image = pn.render_shaded(cloud, cam, TRANSLUCENT, lights=[SUN], level=level)
    against_level_0, against_means = ZOOMED_OUT[level]
    assert psnr(image, level_0) >= against_level_0
    assert psnr(image, means) >= against_means
    assert psnr(image, means) >= psnr(level_0, means) - 1.0


@pytest.mark.parametrize("magnification, level", [(2.0, 0), (1 / 2, 0), (1 / 8, 0), (1 / 16, 1), (1 / 32, 2)])
def test_automatic_levels_keep_voxels_at_most_an_eighth_of_a_pixel(cloud, magnification, level):
    """`level='auto'`: the coarsest level whose voxels project to at most 1/8 pixel (1/2^k of the magnification);
    the default renders level 0 at any magnification."""
    cam = camera(cloud, "ortho", magnification, direction=VIEW)
    stats, default = {}, {}
    pn.render_shaded(cloud, cam, TRANSLUCENT, lights=[SUN], level="auto", stats=stats)
    pn.render_shaded(cloud, cam, TRANSLUCENT, lights=[SUN], stats=default)
    assert stats["level"] == level and default["level"] == 0
    stats = {}
    pn.render_mip(cloud, cam, level="auto", stats=stats)
    assert stats["level"] == level


@pytest.mark.parametrize("level", [-1, "fast", 1.5])
def test_bad_levels_are_refused(cloud, level):
    cam = camera(cloud, "ortho", 1 / 8)
    with pytest.raises(ValueError, match="level"):
        pn.render_shaded(cloud, cam, TRANSLUCENT, level=level)
    with pytest.raises(ValueError, match="level"):
        pn.render_mip(cloud, cam, level=level)
