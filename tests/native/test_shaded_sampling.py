"""Sheets sampled instead of splatted (src/shaded/sheets/sheet_sampling.h).

Where a grid's footprints cover a few pixels (some of it splatted at stride 1), `pcvr` fills its sheets by
interpolating the grid's prefiltered lattice at the pixels that may be seen, instead of splatting every voxel
into every sheet it reaches. The reconstruction differs from the splats' (trilinear interpolation of the
blurred voxels against gauss1.4), so the images are compared with the ray caster and with the splats, with
thresholds 1.5 dB below what was measured on these phantoms (their one-voxel edges are the hardest case):

| scene (512^2-like magnification 1.5, one sun) | splats vs ray caster | sampled vs ray caster | sampled vs splats |
|---|---|---|---|
| CT phantom 64^3, bone, perspective | 34.9 dB | 34.2 dB | 36.0 dB |
| CT phantom 64^3, translucent, orthographic | 35.8 | 34.8 | 37.4 |
| Gaussian blobs 32^3, translucent | 58.4 | 57.8 | 60.3 |
| CT phantom 1:1:2 voxels, bone | 34.8 | 34.2 | 33.7 |
| tissue and bone in air, Hounsfield units | 38.3 | 36.6 | 39.0 |

What decides the method is the plan: `auto` samples a grid when its finest stride is 1, `splat` never does,
`sample` always does; MIP and the other methods always splat. A sheet on which a lattice element spans L >= 2
pixels is sampled at the nodes of a stride-L subgrid and post-convolved, as the paper's subgrid is splatted
(measured on the 64^3 CT phantom, bone, magnification 3 in perspective, strides 2 to 4: 33.5 dB against the ray
caster where the splats give 34.3; at magnification 6, stride 4, 33.3 against 34.0, where sampling every pixel
gave 32.7). The choices show in the statistics.
"""

from __future__ import annotations

import numpy as np
import pytest

import pcvr_native as pn

from shaded_scenes import (SUN, TISSUE_AND_BONE, anisotropic_ct_volume, blob_volume, bone_tf, camera, ct_volume,
                           heads_in_air, psnr)


def translucent() -> pn.TransferFunction:
    return pn.TransferFunction(density=[0.0, 0.1, 0.5, 1.0],
                               rgba=[[0, 0, 0, 0], [0.9, 0.5, 0.3, 0.05], [0.9, 0.8, 0.6, 0.2], [1, 1, 1, 0.6]])


# scene: (volume, transfer function, projection, magnification, least dB against the ray caster, against the splats).
# Tests take them by name: pytest's marks and parameters, kept to the end of the session, then hold nothing that
# leads to native objects (nanobind reports those still alive at exit as leaks).
SCENES = {
    "ct-bone": (lambda: ct_volume(64), bone_tf, "persp", 1.5, 32.7, 34.5),
    "ct-translucent": (lambda: ct_volume(64), translucent, "ortho", 1.0, 33.3, 35.9),
    "blobs": (lambda: blob_volume(32), translucent, "persp", 1.5, 56.3, 58.8),
    "anisotropic-ct-bone": (lambda: anisotropic_ct_volume(64), bone_tf, "persp", 1.5, 32.7, 32.2),
    "hounsfield-units": (lambda: heads_in_air(32)[0], lambda: TISSUE_AND_BONE, "persp", 1.5, 35.1, 37.5),
}


@pytest.mark.parametrize("name", list(SCENES))  # the mark keeps its arguments: names, not the table
def test_sampled_sheets_match_the_ray_caster_and_the_splats(name):
    volume, tf, projection, magnification, against_ray_caster, against_splats = SCENES[name]
    grid, tf = volume(), tf()
    cam = camera(grid, projection, magnification)
    reference = pn.render_shaded(grid, cam, tf, lights=[SUN], method="raycast", sheet_spacing=0.1)
    stats = {}
    sampled = pn.render_shaded(grid, cam, tf, lights=[SUN], stats=stats)
    splatted = pn.render_shaded(grid, cam, tf, lights=[SUN], sheet_fill="splat")
    assert stats["grids_sampled"] == 1 and stats["voxels"] == 0 and stats["sheet_samples"] > 0
    assert psnr(sampled, reference) >= against_ray_caster
    assert psnr(sampled, splatted) >= against_splats


def test_the_automatic_choice_follows_the_magnification():
    grid = ct_volume(64)
    low, high = {}, {}
    pn.render_shaded(grid, camera(grid, "persp", 1.0), bone_tf(), lights=[SUN], stats=low)
    pn.render_shaded(grid, camera(grid, "persp", 6.0), bone_tf(), lights=[SUN], stats=high)
    assert low["grids_sampled"] == 1 and low["strides"] == [1] and low["voxels"] == 0
    assert low["sheet_samples"] > 0 and low["seconds_sampling"] > 0 and low["sampled_strides"] == [1]
    # Splatted post-convolved at strides above 1: nothing sampled.
    assert high["grids_sampled"] == 0 and min(high["strides"]) > 1 and high["voxels"] > 0 and high["sheet_samples"] == 0
    assert high["sampled_strides"] == []


def test_sampling_at_every_magnification_when_asked():
    grid = ct_volume(64)
    stats = {}
    cam = camera(grid, "persp", 6.0)
    image = pn.render_shaded(grid, cam, bone_tf(), lights=[SUN], sheet_fill="sample", stats=stats)
    assert stats["grids_sampled"] == 1 and stats["strides"] == [1] and stats["voxels"] == 0
    assert stats["sampled_strides"] == [4]  # a voxel spans six pixels: the largest subgrid stride sampled
    # Measured at magnification 6: 32.75 dB from the post-convolved splats (31.7 sampling every pixel); against the
    # ray caster (every third pixel) 33.3 dB, the splats 34.0 dB. Where the automatic choice splats, it is the more
    # accurate too.
    assert psnr(image, pn.render_shaded(grid, cam, bone_tf(), lights=[SUN], sheet_fill="splat")) >= 31.2


def test_sheets_on_which_voxels_span_pixels_are_sampled_on_a_subgrid_and_post_convolved():
    # Magnification 3 in perspective: each sheet's stride from its own magnification (the near ones coarser).
    grid = ct_volume(64)
    cam = camera(grid, "persp", 3.0)
    stats = {}
    image = pn.render_shaded(grid, cam, bone_tf(), lights=[SUN], sheet_fill="sample", stats=stats)
    assert stats["grids_sampled"] == 1 and stats["voxels"] == 0 and min(stats["sampled_strides"]) >= 2
    reference = pn.render_shaded(grid, cam, bone_tf(), lights=[SUN], method="raycast", sheet_spacing=0.1, pixel_step=3)
    splatted = pn.render_shaded(grid, cam, bone_tf(), lights=[SUN], sheet_fill="splat")
    # Measured 33.5 dB against the ray caster (the splats 34.3) and 35.0 against the splats: 1.5 dB below.
    assert psnr(image[::3, ::3], reference) >= 32.0
    assert psnr(image, splatted) >= 33.5


@pytest.mark.parametrize("method", ["regular", "bilinear_spread"])
def test_other_methods_splat(method):
    grid = ct_volume(32)
    stats = {}
    pn.render_shaded(grid, camera(grid, "persp", 1.0), bone_tf(), lights=[SUN], method=method, stats=stats)
    assert stats["grids_sampled"] == 0 and stats["voxels"] > 0
    with pytest.raises(ValueError, match="sheet_fill 'sample' is only supported by method 'pcvr'"):
        pn.render_shaded(grid, camera(grid, "persp", 1.0), bone_tf(), method=method, sheet_fill="sample")


def test_mip_splats_and_unknown_fills_are_refused():
    grid = ct_volume(32)
    stats = {}
    pn.render_mip(grid, camera(grid, "persp", 1.0), stats=stats)
    assert stats["grids_sampled"] == 0 and stats["voxels"] > 0
    with pytest.raises(ValueError, match="unknown sheet_fill 'gather' \\(expected auto, splat or sample\\)"):
        pn.render_shaded(grid, camera(grid, "persp", 1.0), bone_tf(), sheet_fill="gather")


def test_two_grids_are_sampled_each_from_its_own_lattice():
    # Two overlapping heads, one shifted by 0.6 of its width: the sampled pair against the splatted pair (measured
    # 33.9 dB; against the ray caster 33.9 and 35.8 dB).
    a = ct_volume(32)
    xf = np.asarray(a.index_to_world).copy()
    xf[0, 3] += 0.6
    b = a.with_index_to_world(xf)
    cam = camera(a, "persp", 1.0)
    stats = {}
    sampled = pn.render_shaded([a, b], cam, bone_tf(), lights=[SUN], stats=stats)
    splatted = pn.render_shaded([a, b], cam, bone_tf(), lights=[SUN], sheet_fill="splat")
    assert stats["grids_sampled"] == 2
    assert psnr(sampled, splatted) >= 32.4


def test_brick_visibility_is_made_once_per_visible_span_and_kept_with_the_lattice():
    # Which lattice bricks may show depends on the transfer function's visible span, not on the view or the lights:
    # the first render of a span makes it, later ones take it from the grid's lattice (viewport redraws, camera
    # paths, light sweeps) and render exactly as a grid that makes it afresh.
    grid = ct_volume(64)
    persp, ortho = camera(grid, "persp", 1.5), camera(grid, "ortho", 1.0)
    other_sun = pn.Light.sun(direction=(0.3, 0.5, -0.8))

    def render(volume, cam, tf, light=SUN):
        stats = {}
        image = pn.render_shaded(volume, cam, tf, lights=[light], stats=stats)
        assert stats["grids_sampled"] == 1
        return image, (stats["brick_visibility_built"], stats["brick_visibility_reused"])

    assert render(grid, persp, bone_tf())[1] == (1, 0)
    for cam, light in ((persp, SUN), (ortho, SUN), (persp, other_sun)):
        image, made = render(grid, cam, bone_tf(), light)
        fresh, made_fresh = render(ct_volume(64), cam, bone_tf(), light)
        assert made == (0, 1) and made_fresh == (1, 0)
        assert np.array_equal(image, fresh)
    assert render(grid, persp, translucent())[1] == (1, 0)  # another span: made, and kept beside the first
    assert render(grid, persp, bone_tf())[1] == (0, 1)


def corner_blobs_grid(side: int) -> pn.Grid:
    """A `side`^3 box holding two small blobs at opposite corners (read slab by slab: only they are stored)."""
    shape = (side, side, side)

    def slabs(planes=20):
        for i0 in range(0, side, planes):
            slab = np.zeros((min(planes, side - i0), side, side), dtype=np.float32)
            for corner in (0, side - 6):
                for i in range(max(corner, i0), min(corner + 6, i0 + len(slab))):
                    slab[i - i0, corner:corner + 6, corner:corner + 6] = 1.0
            yield slab

    return pn.Grid.from_slabs(slabs(), shape, np.eye(4))


def test_a_grid_past_the_old_lattice_cap_is_sampled_when_memory_allows():
    # A 420^3 box: 76M lattice elements, past the 2^26 that once sent clinical-size CT heads (512 x 512 x 250) to
    # the splats; the lattice is bounded by the memory limit now (4.25 bytes a voxel, a quarter of what is free).
    grid = corner_blobs_grid(420)
    cam = camera(grid, "persp", 0.25)
    stats = {}
    sampled = pn.render_shaded(grid, cam, bone_tf(), lights=[SUN], stats=stats)
    assert stats["grids_sampled"] == 1 and stats["voxels"] == 0 and stats["sheet_samples"] > 0
    splatted = pn.render_shaded(grid, cam, bone_tf(), lights=[SUN], sheet_fill="splat")
    assert np.count_nonzero(sampled[..., 3] > 0.1) > 0
    # Measured 70.1 dB against the splats (the blobs cover a few pixels of the 187 x 186 image).
    assert psnr(sampled, splatted) >= 60.0
