"""Gradient opacity: a transfer function's opacity times a piecewise-linear function of |grad density| (density
units per world unit), applied before opacity correction, in the sheet walk and in the ray caster alike.

The magnitude's scale is checked on a linear ramp of known slope under a rotated, anisotropic transform, seen
along its gradient (orthographic and perspective): the factor is read off the alpha of a ray through a band of
densities, whose length the slope gives. The factors fall from 1 to 0 over the magnitudes: the ramp's ends,
where the field drops to the background, have large gradients and so stay transparent."""

from __future__ import annotations

import math

import numpy as np
import pytest

import pcvr_native as pn

from gradient_scenes import band_alpha, band_tf, middle, ramp, ramp_camera
from shaded_scenes import SUN, blob_volume, bone_tf, camera, psnr

OPACITY, UNIT = 0.2, 0.25  # per unit distance 0.25 world units: the band (2 world units) is 8 of them


@pytest.fixture(scope="module")
def scene():
    return ramp()


def render_band(scene, cam, method, gradient, factors):
    """The ray caster samples every 0.1 voxel: its analytic gradient ripples with the kernels' sum (between
    0.95 and 1.03 of a ramp's slope), which sparse samples would alias."""
    tf = band_tf(scene.band, OPACITY, UNIT, gradient=gradient, gradient_opacity=factors)
    return pn.render_shaded(scene.grid, cam, tf, lights=[SUN], method=method, opacity_cutoff=1.0,
                            sheet_spacing=0.1 if method == "raycast" else 1.0)


# Factor (at the slope 3) of three gradient-opacity functions: 1 below 3.6 falling to 0 at 4; 1 at 2 falling
# to 0 at 4 (0.5 at 3); 1 at 1.6 falling to 0 from 2.
CASES = [((3.6, 4.0), 1.0), ((2.0, 4.0), 0.5), ((1.6, 2.0), 0.0)]


@pytest.mark.parametrize("projection", ["ortho", "persp"])
@pytest.mark.parametrize("method", ["pcvr", "raycast"])
@pytest.mark.parametrize("gradient, factor", CASES, ids=["factor-1", "factor-0.5", "factor-0"])
def test_the_gradient_magnitude_is_density_per_world_unit(scene, projection, method, gradient, factor):
    cam = ramp_camera(scene, projection)
    alpha = middle(render_band(scene, cam, method, gradient, (1.0, 0.0)))[..., 3]
    expected = band_alpha(scene, OPACITY, factor, UNIT)
    # Measured: the analytic alpha (0.832, 0.570, 0) to 0.001 (pcvr) and 0.009 (the ray caster, whose point
    # samples see the ripple of the kernels' sum). A magnitude 1.7% off would move the factor-0.5 case by 0.02.
    assert np.abs(alpha - expected).max() < 0.02, (alpha, expected)


@pytest.mark.parametrize("scale", [1e-12, 1e9])
@pytest.mark.parametrize("method", ["pcvr", "raycast"])
def test_the_magnitude_holds_at_extreme_scales(method, scale):
    """Voxels 1e-12 and 1e9 world units wide, the slope and the magnitudes scaled to match: the same alpha
    (measured: within 0.001 of the scale-1 scene's); the walk divides its frame's determinant out first."""
    scaled = ramp(slope=3.0 / scale, spacing=tuple(np.multiply((0.5, 0.8, 0.35), scale)))
    tf = band_tf(scaled.band, OPACITY, UNIT * scale, gradient=[2.0 / scale, 4.0 / scale], gradient_opacity=[1.0, 0.0])
    image = pn.render_shaded(scaled.grid, ramp_camera(scaled, "ortho"), tf, lights=[SUN], method=method,
                             opacity_cutoff=1.0, sheet_spacing=0.1 if method == "raycast" else 1.0)
    assert np.abs(middle(image)[..., 3] - band_alpha(scaled, OPACITY, 0.5, UNIT * scale)).max() < 0.02


def test_constant_factors_equal_a_scaled_opacity(scene):
    """A factor f everywhere is the transfer function with opacity a f: exactly, since the factor applies
    before the opacity becomes an extinction."""
    cam = ramp_camera(scene, "ortho")
    modulated = render_band(scene, cam, "pcvr", [0.0], [0.5])
    scaled = pn.render_shaded(scene.grid, cam, band_tf(scene.band, OPACITY * 0.5, UNIT), lights=[SUN], opacity_cutoff=1.0)
    # Float rounding of the two ways to the same extinction (a table of extinctions, a logarithm per sample).
    assert np.abs(modulated - scaled).max() < 1e-4


# Smooth blobs, as test_shaded_accuracy's: PSNR (dB) of pcvr (Catmull-Rom, two samples per sheet) against the
# ray caster without gradient opacity and with factors rising from 0 at |gradient| 0.1 to 1 at 0.2 (the blobs'
# gradients where they are visible span 0.12 to 0.23 per world unit, 5th to 95th percentile, so the factor
# takes every value; 20% less alpha in all). Measured 55.3 and 55.3 dB without, 46.4 and 49.7 dB with: the
# factor follows the gradient's magnitude, which the walk takes from central differences of post-convolved
# sheets and the ray caster analytically, and a steep factor turns their difference into opacity.
# Thresholds: measured less 2 dB.
PSNR_DB = {"ortho": (53.3, 44.4), "persp": (53.3, 47.7)}


@pytest.mark.parametrize("projection", PSNR_DB)
def test_against_the_ray_caster_on_smooth_blobs(projection):
    grid = blob_volume(24)
    cam = camera(grid, projection, 3.0)
    plain = bone_tf()
    modulated = pn.TransferFunction(density=plain.density, rgba=plain.rgba, gradient=[0.1, 0.2], gradient_opacity=[0.0, 1.0])
    measured, images = [], []
    for tf in (plain, modulated):
        reference = pn.render_shaded(grid, cam, tf, lights=[SUN], method="raycast", sheet_spacing=0.1, opacity_cutoff=1.0)
        images.append(pn.render_shaded(grid, cam, tf, lights=[SUN], opacity_cutoff=1.0))
        measured.append(psnr(images[-1], reference))
    assert all(m >= t for m, t in zip(measured, PSNR_DB[projection])), measured
    # The factor took effect (measured: 80% of the alpha without).
    assert images[1][..., 3].sum() < 0.9 * images[0][..., 3].sum()


def test_factors_of_zero_leave_nothing_unshaded(scene):
    cam = ramp_camera(scene, "ortho")
    nothing = pn.TransferFunction(density=[-100.0, 100.0], rgba=[[1, 1, 1, 1]] * 2, gradient=[0.0], gradient_opacity=[0.0])
    stats = {}
    image = pn.render_shaded(scene.grid, cam, nothing, lights=[SUN], stats=stats)
    assert not image.any()
    assert stats["samples_shaded"] == 0
    plain = pn.TransferFunction(density=[-100.0, 100.0], rgba=[[1, 1, 1, 1]] * 2)
    assert pn.render_shaded(scene.grid, cam, plain, lights=[SUN])[..., 3].max() > 0.99


def test_attributes_and_defaults():
    tf = pn.TransferFunction(density=[0.0, 1.0], rgba=[[1, 1, 1, 0], [1, 1, 1, 1]], gradient=[0.0, 2.5],
                             gradient_opacity=np.array([0.25, 1.0]))
    assert tf.gradient == [0.0, 2.5] and tf.gradient_opacity == [0.25, 1.0]
    plain = pn.TransferFunction(density=[0.0, 1.0], rgba=[[1, 1, 1, 0], [1, 1, 1, 1]])
    assert plain.gradient == [] and plain.gradient_opacity == []
    assert pn.TransferFunction(density=[0.0], rgba=[[1, 1, 1, 1]], gradient=[], gradient_opacity=[]).gradient == []


@pytest.mark.parametrize("gradient, factors, message", [
    ([0.0, 1.0], [1.0], "2 gradient magnitudes but 1 gradient_opacity"),
    ([1.0], None, "1 gradient magnitudes but 0 gradient_opacity"),
    (None, [1.0], "0 gradient magnitudes but 1 gradient_opacity"),
    ([1.0, 1.0], [0.0, 1.0], "gradient magnitudes must increase"),
    ([2.0, 1.0], [0.0, 1.0], "gradient magnitudes must increase"),
    ([-1.0, 1.0], [0.0, 1.0], "gradient point 0: the gradient magnitude must be finite and not negative"),
    ([0.0, math.inf], [0.0, 1.0], "gradient point 1: the gradient magnitude must be finite"),
    ([0.0, 1.0], [0.0, 1.5], "gradient point 1: gradient_opacity must lie in \\[0, 1\\]"),
    ([0.0, 1.0], [math.nan, 1.0], "gradient point 0: gradient_opacity must lie in \\[0, 1\\]"),
])
def test_bad_gradient_opacity_is_refused_with_a_reason(gradient, factors, message):
    with pytest.raises(ValueError, match=message):
        pn.TransferFunction(density=[0.0, 1.0], rgba=[[1, 1, 1, 0], [1, 1, 1, 1]], gradient=gradient, gradient_opacity=factors)
