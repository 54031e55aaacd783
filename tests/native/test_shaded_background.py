"""Grids whose inactive voxels hold a background other than 0: a CT scan in Hounsfield units stores
air (-1000) as inactive background. Beyond the active voxels the density is the background, so the
reconstruction must fall towards -1000, not towards 0: falling to 0 passes through soft tissue's
densities and draws a false shell of tissue around the active region (a red rim under CT Bone).

The check: the same head stored sparsely (air inactive at background -1000) and densely (air
active at -1000.001) renders the same, by every method. Measured: 2.2e-6 (shaded), 0.016 HU (MIP);
without the background both differ by whole shells of opacity."""

from __future__ import annotations

import numpy as np
import pytest

import pcvr_native as pn

from shaded_scenes import AIR, SUN, TISSUE_AND_BONE, camera, heads_in_air, psnr


@pytest.fixture(scope="module")
def heads():
    """A ball of soft tissue (40 HU) with a bone core (700 HU) in air: sparse and dense."""
    sparse, dense = heads_in_air(32)
    assert sparse.background == AIR and sparse.active_voxel_count < dense.active_voxel_count == 32 ** 3
    return sparse, dense


@pytest.mark.parametrize("projection", ["ortho", "persp"])
@pytest.mark.parametrize("method", ["regular", "pcvr", "bilinear_spread", "raycast"])
def test_inactive_air_renders_as_active_air(heads, projection, method):
    sparse, dense = heads
    cam = camera(sparse, projection, 3.0)
    kw = dict(lights=[SUN], method=method, **(dict(sheet_spacing=0.5) if method == "raycast" else {}))
    image = pn.render_shaded(sparse, cam, TISSUE_AND_BONE, **kw)
    assert image[..., 3].max() > 0.9
    assert np.abs(image - pn.render_shaded(dense, cam, TISSUE_AND_BONE, **kw)).max() < 1e-4


# Measured PSNR against the ray caster (dB), minus 2: regular, pcvr.
THRESHOLDS = {"ortho": (33.6, 31.3), "persp": (34.3, 33.6)}


@pytest.mark.parametrize("projection", ["ortho", "persp"])
def test_splatting_reconstructs_the_background_as_the_ray_caster_does(heads, projection):
    sparse, _ = heads
    cam = camera(sparse, projection, 3.0)
    reference = pn.render_shaded(sparse, cam, TISSUE_AND_BONE, lights=[SUN], method="raycast", sheet_spacing=0.1)
    for method, threshold in zip(("regular", "pcvr"), THRESHOLDS[projection]):
        assert psnr(pn.render_shaded(sparse, cam, TISSUE_AND_BONE, lights=[SUN], method=method), reference) >= threshold


@pytest.mark.parametrize("method", ["regular", "pcvr", "raycast"])
def test_mip_never_falls_below_the_background(heads, method):
    sparse, dense = heads
    cam = camera(sparse, "persp", 3.0)
    image = pn.render_mip(sparse, cam, method=method)
    assert image[0, 0] == AIR  # a ray that meets no voxel crosses only air
    assert image.min() >= AIR and image.max() > 600
    assert np.abs(image - pn.render_mip(dense, cam, method=method)).max() < 0.1
