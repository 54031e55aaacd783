"""What the shaded renderer skips must not show, and what it skips is counted.

* Transparent blocks: a block is culled only when every sample its voxels (or their absence) can
  reach is transparent with and without it (transparency_culling.h, CullingReach), so culling changes no pixel:
  the images with and without it are compared bit for bit, on a CT phantom large enough that its
  brain blocks are culled under a transfer function that shows only the skull. The 4^3 bricks of the
  blocks that are kept, then their single voxels, are culled by the same test on their own
  neighbourhoods, under the same flag (transparency_culling.h).
* Occlusion: once a pixel passes opacity_cutoff it takes no more samples, so the image changes by at
  most (1 - cutoff) times the brightest lit colour (transfer-function colour 1 times ambient 0.1 plus
  diffuse 0.9, plus specular 0.2: 1.2), within 1/255 at 0.999; voxels that reach only such pixels
  are not splatted, which changes nothing more. Behind the 4-voxel opaque front slab of a 32^3 block,
  87.5% of the voxels are hidden, but those within about 5 voxels of the block's sides also reach
  pixels beside it, which never turn opaque (the kernel's radius, the post-filter and the gradient
  stencil): 87.5% of the inner 22^2 columns is 41%, and 40-43% of the deposits are culled (measured
  at cutoffs 0.99-0.999).
* Tiles: the tile size changes how work is split, not the image, except for float rounding: the order
  in which a node sums its voxels depends on where its tile's walk starts (densities agree to 1e-5 of
  the peak), and shading amplifies that where the gradient almost vanishes and the normal is barely
  defined: measured at most 0.23/255 on this scene, 1/255 allowed.
* A transfer function that is transparent everywhere culls every block: nothing is splatted.
"""

from __future__ import annotations

import numpy as np
import pytest

import pcvr_native as pn

from conftest import frame_ortho
from shaded_scenes import SUN, bone_tf, camera, ct_volume

SKULL_ONLY = pn.TransferFunction(density=[0.0, 0.45, 0.6, 1.0],
                                 rgba=[[0, 0, 0, 0], [0.8, 0.4, 0.3, 0.0], [0.9, 0.8, 0.6, 0.2], [1, 1, 1, 0.9]])


@pytest.fixture(scope="module")
def big_ct():
    return ct_volume(128)


@pytest.mark.parametrize("method, post, fill, magnification",
                         [("regular", "bilinear", "splat", 1.0), ("pcvr", "bilinear", "splat", 1.0),
                          ("pcvr", "catmull_rom", "splat", 1.0), ("bilinear_spread", "bilinear", "splat", 1.0),
                          ("pcvr", "catmull_rom", "sample", 1.0), ("pcvr", "catmull_rom", "sample", 3.0),
                          ("pcvr", "bilinear", "sample", 3.0)])
def test_culling_transparent_blocks_changes_no_pixel(big_ct, method, post, fill, magnification):
    # Sampled sheets (sheet_sampling.h) take no voxels from the culled blocks' cells, and leave at 0 the values
    # no sample that may be visible reads: measured 0.82M values interpolated (0.63M left at 0) with culling,
    # 1.47M without. At magnification 3 they are sampled on subgrids of stride 2 to 4 and post-convolved; the
    # bilinear post filter (no negative lobes) lets the brick ranges skip nodes there too.
    cam = camera(big_ct, "persp", magnification)
    culled, kept = {}, {}
    a = pn.render_shaded(big_ct, cam, SKULL_ONLY, lights=[SUN], method=method, post_filter=post, stats=culled, sheet_fill=fill)
    b = pn.render_shaded(big_ct, cam, SKULL_ONLY, lights=[SUN], method=method, post_filter=post, stats=kept,
                         cull_transparent=False, sheet_fill=fill)
    assert culled["blocks_transparent"] >= 0.1 * culled["blocks"]  # measured 214 of 1534
    assert kept["blocks_transparent"] == 0
    work = "sheet_samples" if fill == "sample" else "voxels"
    # Culled blocks mark no cells; on Catmull-Rom subgrids, whose wanted nodes are all interpolated, the margins
    # of the cells that stay hold most of what the culled ones would have: measured 2.36M values against 2.42M.
    most = 1.0 if fill == "sample" and magnification > 1.0 and post != "bilinear" else 0.9
    assert culled[work] <= most * kept[work]
    if magnification > 1.0:
        assert min(culled["sampled_strides"]) >= 2
        assert (culled["sheet_samples_skipped"] > 0) == (post == "bilinear")
    assert np.array_equal(a, b)


@pytest.mark.parametrize("magnification, post", [(1.0, "catmull_rom"), (3.0, "bilinear")])
def test_sampled_sheets_skip_through_the_tight_brick_ranges(big_ct, magnification, post):
    # A value's reach (two sheets along the ray and a gradient step, per axis) fits the lattice's brick ranges
    # over 4 elements on this view, so those decide which values no visible sample reads (the test above
    # checks that skipping changes no pixel). Measured share of the candidate values interpolated: 0.45 at
    # magnification 1 (653,784 of 1,453,216) and 0.47 at 3 (1,126,864 of 2,385,768), against 0.56 and 0.60
    # through the ranges over 6 elements alone.
    stats = {}
    pn.render_shaded(big_ct, camera(big_ct, "persp", magnification), SKULL_ONLY, lights=[SUN], post_filter=post, stats=stats,
                     sheet_fill="sample")
    candidates = stats["sheet_samples"] + stats["sheet_samples_skipped"]
    assert stats["sheet_samples"] <= 0.5 * candidates


def test_culling_transparent_bricks_and_voxels_of_listed_blocks(big_ct):
    # Blocks holding the skull's inner edge also hold brain voxels whose neighbourhoods are transparent: 4^3
    # bricks are left out from their bricks' ranges, then single voxels from each voxel's own (within the
    # culling reach, Grid::voxel_value_ranges). Measured: 404 bricks of 1268 listed blocks, then 61,588 voxels
    # (18.5% of the 331,813 splatted; blocks whose every voxel goes count as transparent: 266 of 1534, against
    # 214 from the blocks' ranges alone). No pixel changes (the test above compares the images bit for bit).
    culled, kept = {}, {}
    cam = camera(big_ct, "persp", 1.0)
    pn.render_shaded(big_ct, cam, SKULL_ONLY, lights=[SUN], stats=culled)
    pn.render_shaded(big_ct, cam, SKULL_ONLY, lights=[SUN], stats=kept, cull_transparent=False)
    assert culled["bricks_transparent"] >= 0.03 * 8 * culled["blocks_listed"]
    assert culled["voxels_transparent"] >= 0.1 * culled["voxels"]
    assert kept["bricks_transparent"] == kept["voxels_transparent"] == 0


def front_slab_volume(n=32):
    values = np.full((n, n, n), 0.5, np.float32)
    values[:, :, n - 4:] = 1.0  # k is world z: the camera looks down -z, so these voxels are in front
    return pn.Grid.from_dense(values, np.eye(4))


FRONT_SLAB_TF = pn.TransferFunction(density=[0.0, 0.4, 1.0], rgba=[[0, 0, 0, 0], [0.6, 0.6, 0.9, 0.3], [1, 0.9, 0.8, 0.99]])


@pytest.mark.parametrize("cutoff", [0.99, 0.999])
def test_occlusion_culls_what_an_opaque_front_hides(cutoff):
    grid = front_slab_volume()
    cam = frame_ortho(grid, 3.0, direction=(0.1, 0.05, -1.0)).camera()
    culled, full = {}, {}
    # The bilinear post filter: its reach (one node) is what the 5-voxel band below assumes.
    a = pn.render_shaded(grid, cam, FRONT_SLAB_TF, lights=[SUN], opacity_cutoff=cutoff, stats=culled, post_filter="bilinear")
    b = pn.render_shaded(grid, cam, FRONT_SLAB_TF, lights=[SUN], opacity_cutoff=1.0, stats=full, post_filter="bilinear")
    assert full["voxels_occluded"] == 0
    assert culled["voxels_occluded"] >= 0.35 * (culled["voxels"] + culled["voxels_occluded"])
    brightest = 0.1 + 0.9 + 0.2
    assert np.abs(a - b).max() <= (1.0 - cutoff) * brightest + 1e-6
    if cutoff == 0.999:
        assert np.abs(a - b).max() <= 1 / 255


def test_tile_size_does_not_change_the_image():
    grid = ct_volume(40)
    cam = camera(grid, "persp", 2.0)
    images = [pn.render_shaded(grid, cam, bone_tf(), lights=[SUN], tile_size=t, samples_per_sheet=2) for t in (16, 64, 1000)]
    for image in images[1:]:
        assert np.abs(image - images[0]).max() <= 1 / 255


def test_automatic_tiles_follow_the_image_not_the_threads():
    """128 to 256 pixels: at least 64 subgrid nodes, else some 32 tiles to the image; never from the threads
    (tiles decide what the occlusion map culls, and the image must not change with the threads)."""
    grid = ct_volume(40)
    # 128 (the least), the image's share (regular's stride 1 at 1000 x 1000: 176), 64 nodes, 256 (the most).
    for method, magnification in (("pcvr", 2.0), ("regular", 16.0), ("pcvr", 8.0), ("pcvr", 24.0)):
        cam = camera(grid, "persp", magnification)
        stats = [{}, {}]
        images = [pn.render_shaded(grid, cam, bone_tf(), lights=[SUN], method=method, threads=t, stats=s)
                  for t, s in zip((1, 2), stats)]
        nodes = 64 * min(stats[0]["strides"])
        expected = min(max(nodes, int(np.sqrt(cam.width * cam.height / 32))), 256)
        assert stats[0]["tile_size"] == stats[1]["tile_size"] == max(128, expected), (method, magnification)
        np.testing.assert_array_equal(images[0], images[1])
    stats = {}
    pn.render_shaded(grid, cam, bone_tf(), lights=[SUN], tile_size=100, stats=stats)
    assert stats["tile_size"] == 100 and stats["tiles"] == -(-cam.width // 100) * -(-cam.height // 100)


def test_a_transparent_transfer_function_costs_almost_nothing(big_ct):
    cam = camera(big_ct, "ortho", 1.0)
    clear = pn.TransferFunction(density=[0.0, 1.0], rgba=[[1, 1, 1, 0], [1, 1, 1, 0]])
    stats = {}
    image = pn.render_shaded(big_ct, cam, clear, lights=[SUN], stats=stats)
    assert not image.any()
    assert stats["blocks_transparent"] == stats["blocks"] - stats["blocks_outside"] > 0
    assert stats["voxels"] == 0 and stats["tile_sheets_composited"] == 0
