"""Exact relations the shaded renderer must keep, whatever the data.

* Sheets sum to the X-ray. With a transfer function whose extinction is k * density (white, opacity
  1 - exp(-k d u) per slab of thickness u) and no early termination, compositing gives
  1 - alpha = exp(-k * sum over sheets of density * ray length), so -ln(1 - alpha) / k is the sum of the
  sheets: the slab footprints of every voxel add up to its X-ray footprint, for every sheet spacing.
  With one sample per sheet it must equal render_xray of the same method (same stride), with the paper's
  passband (the sheets have no passband compensation):
  - regular, orthographic: 2e-3 of the peak (REGULAR_TOL in conftest: the X-ray takes orthographic
    windows from phase tables, interpolated to 1e-4 of the peak RMS and 7e-4 at worst; the sheets
    look each tap up in the footprint table; measured 1.7e-4);
  - regular, perspective: both evaluate the same linearised footprint per voxel and tap: 2e-4
    (measured 4e-5: float rounding of the sums and of the opacity table, 1e-5 relative);
  - pcvr at a fixed stride, both projections: as regular (the post-convolution is linear);
  - bilinear_spread, orthographic: 1e-4 (both spread each voxel's whole mass; measured 1.4e-6).
  With more samples the Catmull-Rom cubic between sheets would keep the sum, but it is clamped to the
  range of the two sheets around each sample (src/shaded/sheets/sheet_walk_compositing.cpp, AlongRay), which flattens peaks
  between sheets: 5e-3 (measured 3.4e-3, at the phantom's one-voxel skull).
* The image does not depend on the number of threads (tiles are rendered one thread each): bit-equal.
* The opacity correction: halving the sheet spacing keeps the optical depth of a volume to float
  rounding (it is the same X-ray).
"""

from __future__ import annotations

import numpy as np
import pytest

import pcvr_native as pn

from conftest import REGULAR_TOL
from shaded_scenes import SUN, bone_tf, camera, ct_volume, optical_depth, optical_depth_tf

K = 1.0  # extinction per unit density per world unit: the phantom's line integrals stay below ~0.5


@pytest.fixture(scope="module")
def ct():
    return ct_volume(24)


CUBIC_TOL = 5e-3


def optical_render(grid, cam, method, **kw):
    kw.setdefault("opacity_cutoff", 1.0)
    kw.setdefault("samples_per_sheet", 1)
    kw.setdefault("cull_transparent", False)
    return optical_depth(pn.render_shaded(grid, cam, optical_depth_tf(K, 1.2), method=method, **kw), K)


@pytest.mark.parametrize("projection", ["ortho", "persp"])
@pytest.mark.parametrize("spacing, samples", [(1.0, 1), (0.5, 1), (1.0, 3), (0.37, 2)])
def test_sheets_of_regular_splatting_sum_to_the_xray(ct, projection, spacing, samples):
    cam = camera(ct, projection, 3.0)
    stats = {}
    sheets = optical_render(ct, cam, "regular", sheet_spacing=spacing, samples_per_sheet=samples, stats=stats)
    xray = pn.render_xray(ct, cam, method="regular", passband="paper").astype(np.float64)
    tolerance = max(REGULAR_TOL if projection == "ortho" else 2e-4, CUBIC_TOL if samples > 1 else 0.0)
    assert np.abs(sheets - xray).max() <= tolerance * xray.max()


# Measured (largest difference over the largest integral): regular 1.76e-4 with the AVX2 build, 2.11e-4 with the
# x86-64 one (its scalar paths, make test-no-avx2); pcvr 0.78e-4 and 0.93e-4. About a fifth above the worst.
LINEARISED_TOL = {"regular": 2.5e-4, "pcvr": 1.2e-4}


@pytest.mark.parametrize("method", ["regular", "pcvr"])
def test_sheets_of_linearised_blocks_sum_to_the_xray(ct, method):
    """Far enough from the eye (here 12 half-diagonals), a block's footprints come from its affine
    model (block_linearisation.h) in the sheets as in the X-ray: the identity holds for them too."""
    from conftest import frame_perspective
    from shaded_scenes import VIEW
    cam = frame_perspective(ct, 3.0, direction=VIEW, distance=12.0).camera()
    stats, same = {}, {"stride": 2 if method == "pcvr" else 0, "post_filter": "gauss1.4"}
    sheets = optical_render(ct, cam, method, stats=stats, **same)
    xray = pn.render_xray(ct, cam, method=method, passband="paper", **same).astype(np.float64)
    assert stats["blocks_linearised"] == stats["blocks_listed"] > 0
    assert np.abs(sheets - xray).max() <= LINEARISED_TOL[method] * xray.max()


@pytest.mark.parametrize("projection", ["ortho", "persp"])
def test_sheets_of_pcvr_sum_to_the_xray(ct, projection):
    cam = camera(ct, projection, 3.0)
    sheets = optical_render(ct, cam, "pcvr", stride=2, post_filter="gauss1.4", sheet_spacing=0.7)
    xray = pn.render_xray(ct, cam, method="pcvr", stride=2, post_filter="gauss1.4", passband="paper").astype(np.float64)
    tolerance = REGULAR_TOL if projection == "ortho" else 2e-4
    assert np.abs(sheets - xray).max() <= tolerance * xray.max()


def test_sheets_of_bilinear_spreading_sum_to_the_xray(ct):
    cam = camera(ct, "ortho", 3.0)
    sheets = optical_render(ct, cam, "bilinear_spread", post_filter="bilinear")
    xray = pn.render_xray(ct, cam, method="bilinear_spread", post_filter="bilinear", passband="paper").astype(np.float64)
    assert np.abs(sheets - xray).max() <= 1e-4 * xray.max()


@pytest.mark.parametrize("method", ["regular", "pcvr", "bilinear_spread"])
def test_any_thread_count_gives_the_same_image(ct, method):
    cam = camera(ct, "persp", 2.5)
    images = [pn.render_shaded(ct, cam, bone_tf(), lights=[SUN], method=method, threads=t, samples_per_sheet=2,
                               tile_size=16) for t in (1, 2, 3)]
    assert np.array_equal(images[0], images[1]) and np.array_equal(images[0], images[2])


def test_mip_does_not_depend_on_the_thread_count(ct):
    cam = camera(ct, "ortho", 2.0)
    images = [pn.render_mip(ct, cam, threads=t, tile_size=16) for t in (1, 2)]
    assert np.array_equal(images[0], images[1])


SHAPE = (10, 9, 7)


def oblique_view(part: str, values: np.ndarray):
    """A grid of `values` whose voxels have LINEAR_PARTS[part]'s shape, and a close perspective or
    orthographic view of it from an oblique direction (2.5 pixels per voxel)."""
    from conftest import LINEAR_PARTS
    xf = np.eye(4)
    xf[:3, :3] = LINEAR_PARTS[part]
    return pn.Grid.from_dense(values, xf), xf


def oblique_spec(values: np.ndarray, xf: np.ndarray, projection: str):
    from conftest import frame_ortho, frame_perspective
    frame = frame_ortho if projection == "ortho" else frame_perspective
    return frame((values, xf), 2.5, direction=(0.6, 0.2, -0.5))


def cubic_decoy() -> pn.Grid:
    """One cubic voxel far out of view: with it, anisotropic voxels share no sheet metric with every
    grid, and perspective sheets are world spheres that cut their kernels at an angle."""
    xf = np.eye(4)
    xf[:3, 3] = (1e4, 1e4, 1e4)
    return pn.Grid.from_dense(np.ones((1, 1, 1), np.float32), xf)


@pytest.mark.parametrize("part", ["sheared", "scaled", "stretched"])
@pytest.mark.parametrize("projection", ["ortho", "persp"])
def test_slabs_of_sheared_kernels_sum_to_the_xray(part, projection):
    """Anisotropic and sheared voxels seen obliquely, a cubic grid beside them, so that the sheets are
    the world's (planes of constant depth, spheres) and cut each kernel at an angle: its slabs move
    across the footprint (the per-tap path). Their sum is still the X-ray."""
    values = np.random.default_rng(5).uniform(0.0, 1.0, SHAPE).astype(np.float32)
    grid, xf = oblique_view(part, values)
    cam = oblique_spec(values, xf, projection).camera()
    tf = optical_depth_tf(K, 1.2)
    sheets = optical_depth(pn.render_shaded([grid, cubic_decoy()], cam, [tf, tf], method="regular", opacity_cutoff=1.0,
                                            samples_per_sheet=1, cull_transparent=False), K)
    # The sheets splat linearised footprints everywhere; the X-ray switches to exact ones where the
    # linearisation is off (1.8% here, close to stretched voxels), so it is held to the linearised ones.
    xray = pn.render_xray(grid, cam, method="regular", footprint_tolerance=np.inf, passband="paper").astype(np.float64)
    # Perspective footprints: the slabs take P from its polynomial, the X-ray from its table (the nearest
    # of 4096 samples), 4.4e-4 and 6.8e-4 of P's peak from the line integral (kernel.h): measured up to
    # 2.3e-4 of the image's maximum apart (7.4e-5 when both took the table).
    tolerance = REGULAR_TOL if projection == "ortho" else 3e-4
    assert np.abs(sheets - xray).max() <= tolerance * xray.max()


@pytest.mark.parametrize("part", ["sheared", "scaled", "stretched"])
def test_planes_tilted_into_the_voxels_metric_sum_to_the_xray(part):
    """Orthographic sheets of one anisotropic grid are planes perpendicular to the rays in the metric
    where its voxels are cubes: every tap shares its kernel's slabs, and every ray crosses them at the
    same world length per slab, so the sheets still sum to the X-ray (as in the per-tap test above)."""
    values = np.random.default_rng(5).uniform(0.0, 1.0, SHAPE).astype(np.float32)
    grid, xf = oblique_view(part, values)
    cam = oblique_spec(values, xf, "ortho").camera()
    tf = optical_depth_tf(K, 1.2)
    tilted, depth_planes = {}, {}
    sheets = optical_depth(pn.render_shaded(grid, cam, tf, method="regular", opacity_cutoff=1.0, samples_per_sheet=1,
                                            cull_transparent=False, stats=tilted), K)
    xray = pn.render_xray(grid, cam, method="regular", passband="paper").astype(np.float64)
    assert np.abs(sheets - xray).max() <= REGULAR_TOL * xray.max()
    # A kernel spans 5 slabs in the metric (its diameter of 4 voxels at a spacing of one); the depth
    # planes cut these voxels into 6 (sheared, scaled) to 40 (stretched): measured 5/6 and 1/8 the taps.
    pn.render_shaded([grid, cubic_decoy()], cam, [tf, tf], method="regular", opacity_cutoff=1.0, samples_per_sheet=1,
                     cull_transparent=False, stats=depth_planes)
    assert tilted["voxels"] == depth_planes["voxels"]
    assert (tilted["sheet_metric"], depth_planes["sheet_metric"]) == ("voxels", "world")
    assert tilted["taps"] <= 5 / 6 * depth_planes["taps"]


def line_scales(cam_spec, index_to_world: np.ndarray) -> np.ndarray:
    """World length per index length along each pixel's ray (row 0 on top, pixel centres)."""
    w, h = cam_spec.width, cam_spec.height
    x = (np.arange(w) + 0.5) / w * 2.0 - 1.0
    y = 1.0 - (np.arange(h) + 0.5) / h * 2.0
    ndc = np.stack(np.broadcast_arrays(x[None, :], y[:, None], 1.0, 1.0), axis=-1)
    camera_point = ndc @ np.linalg.inv(cam_spec.projection).T
    direction = camera_point[..., :3] / camera_point[..., 3:]  # from the eye at the camera's origin
    world = direction @ np.linalg.inv(cam_spec.world_to_camera)[:3, :3].T
    index = world @ np.linalg.inv(index_to_world[:3, :3]).T
    return np.linalg.norm(world, axis=-1) / np.linalg.norm(index, axis=-1)


@pytest.mark.parametrize("part", ["sheared", "scaled", "stretched"])
def test_spheres_in_the_voxels_metric_take_each_rays_own_length(part):
    """Perspective sheets are spheres in the metric where a grid's voxels are cubes, so a kernel's slab
    shares hold at every tap, and a slab's world length is each ray's own: one voxel's sheets sum to
    its linearised X-ray footprint times each ray's world length per index length over the central
    ray's (the X-ray takes the central ray's for the whole footprint)."""
    values = np.zeros(SHAPE, np.float32)
    values[5, 4, 3] = 1.0
    grid, xf = oblique_view(part, values)
    spec = oblique_spec(values, xf, "persp")
    cam = spec.camera()
    sheets = optical_render(grid, cam, "regular")
    xray = pn.render_xray(grid, cam, method="regular", footprint_tolerance=np.inf, passband="paper").astype(np.float64)
    eye = np.linalg.inv(spec.world_to_camera)[:3, 3]
    centre_ray = xf[:3, :3] @ np.array([5.0, 4.0, 3.0]) - eye
    centre_scale = np.linalg.norm(centre_ray) / np.linalg.norm(np.linalg.solve(xf[:3, :3], centre_ray))
    predicted = xray * line_scales(spec, xf) / centre_scale
    # The rays' lengths differ across this close voxel's footprint: the sheets are 1-4% of the peak
    # from the X-ray. The prediction holds to what the slabs' polynomial P and the X-ray's table may
    # differ by at one voxel's peak: 4.4e-4 + 6.8e-4 of it (kernel.h; measured 4.8e-4 to 6.3e-4; a
    # whole image's many voxels average it down to the 2.3e-4 above).
    assert np.abs(sheets - xray).max() > 5e-3 * xray.max()
    assert np.abs(sheets - predicted).max() <= 1.2e-3 * xray.max()
