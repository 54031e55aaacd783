"""Property tests (Hypothesis): random small volumes under random affine transforms (rotation,
anisotropic scale, shear, mirror), seen by random orthographic and perspective cameras at random
magnifications, some from inside the volume.

- Orthographic: regular is exact up to its footprint table (REGULAR_TABLE, per kernel).
- Perspective: every linearised footprint is within footprint_tolerance (4%) of its own peak, or
  splatted exactly. Checked on one voxel at a time, from anywhere: the footprint's peak may lie
  outside the image, where errors relative to the image's own peak mean nothing, and X-ray is
  linear (tests/native/test_xray_invariants.py), so a scene's error is the sum of its voxels'.
- With every footprint exact (footprint_tolerance=0) and the eye inside the volume, regular is
  exact up to its table.
- pcvr at a fixed stride L equals its model, exact sampled at the subgrid nodes and post-convolved
  in numpy, to 5e-3 of the peak (measured 3.2e-3: the phase tables; in perspective with exact
  footprints, from inside the volume too). (Against exact
  itself pcvr differs by its post filter's blur, 10-40% of an isolated voxel's peak: that is the
  algorithm, not an error.)
- No method ever returns NaN or infinity.
- Every method returns the same image, bit for bit, for any thread count: measured on 300 + 200
  random scenes and 4 methods. Workers add into their own double-precision grids and the sums are
  added in an unspecified order, so bit equality is not guaranteed in principle; it holds because
  the double sums are rounded to float32 at the end (a difference would need a sum within 1e-16 of
  a float32 rounding boundary). This machine has 2 cores: thread counts above 2 share them.

make test runs 15 examples per property; make stress runs 400 each. Both are derandomised (the same
examples every run), so a failure is reproducible. Earlier make stress runs with fresh seeds found a
bug (phase tables of few phases interpolated footprints narrow in one direction poorly, 0.7% off;
those now go per tap) and showed why perspective is checked per voxel: a voxel whose footprint's
peak lies off the image was 52% off the image's own peak while within 4% of its own.
"""

import math

import numpy as np
from hypothesis import HealthCheck, given, settings, strategies as st

import pcvr_native as pn

from scenes import cameras_for, eyes_inside, grid_of, volumes
from stress_helpers import LONG, METHODS, max_error
from xray_helpers import predict_pcvr, render_xray_paper

# regular's footprint table, per kernel (worst over 300 orthographic examples each): the Gaussians'
# nearest samples in rho^2 (2e-3, see tests/native/conftest.py; measured 9.6e-4); the linear
# kernel's footprint, whose curvature is unbounded at its centre (rho^2 log rho; measured 2.1e-3);
# the box's, whose slope is infinite at its rim (measured 3.2e-3).
REGULAR_TABLE = {"gauss1.4": 2e-3, "gauss2.0": 2e-3, "linear": 4e-3, "box": 6e-3}
# Perspective: each linearised footprint within footprint_tolerance of its own peak (which may lie
# outside the image; X-ray is linear, so a scene's error is the sum of its voxels').
FOOTPRINT_TOLERANCE = 0.04
PHASE_TABLES = 5e-3

PROPERTY = settings(max_examples=400 if LONG else 15, deadline=None, derandomize=True, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
KERNELS = st.sampled_from(["gauss1.4", "gauss2.0", "linear", "box"])


def exact_padded(grid, spec, pad):
    return render_xray_paper(grid, spec.padded(pad).camera(), method="exact").astype(np.float64)


def pcvr_model_error(grid, spec, **options):
    """(pcvr's largest difference from its model, the stride) at the stride every depth band can
    take: that of the least magnified voxels. None when the model shows nothing."""
    cam = spec.camera()
    low, high = pn.effective_magnification(grid, cam)
    stride = max(1, int(math.floor(low + 1e-9))) if high > 0 else 1
    pad = 2 * stride
    model = predict_pcvr(exact_padded(grid, spec, pad), pad, stride, "bilinear", spec.height, spec.width)
    if not np.abs(model).max() > 0:
        return None, stride
    return max_error(render_xray_paper(grid, cam, method="pcvr", stride=stride, antialias=False, **options), model), stride


def footprint_peaks(volume, spec, kernel):
    """Each voxel's line integral along the ray through its centre: the peaks of the footprints,
    wherever they fall."""
    values, xf = volume
    indices = np.argwhere(values != 0).astype(float)
    camera_to_world = np.linalg.inv(spec.world_to_camera)
    world_to_index = np.linalg.inv(xf)
    if spec.orthographic:
        directions = np.tile(world_to_index[:3, :3] @ (camera_to_world[:3, :3] @ [0.0, 0.0, -1.0]), (len(indices), 1))
    else:
        directions = indices - (world_to_index @ np.r_[camera_to_world[:3, 3], 1.0])[:3]
    lengths = np.linalg.norm(directions, axis=1)
    world_lengths = np.linalg.norm(directions @ xf[:3, :3].T, axis=1)
    # A voxel centred on the eye is seen along every direction: its line integral is at most the one
    # along the direction its transform stretches most (the largest singular value).
    world_per_index = np.where(lengths > 0, world_lengths / np.where(lengths > 0, lengths, 1.0), np.linalg.norm(xf[:3, :3], 2))
    centre = pn.kernel_info(kernel)["line_integral_at_centre"]
    return np.abs(values[values != 0]).astype(float) * centre * world_per_index


@PROPERTY
@given(st.data(), KERNELS)
def test_regular_follows_exact(data, kernel):
    """Orthographic views have no linearisation: regular is exact up to its footprint table."""
    volume = data.draw(volumes())
    spec = data.draw(cameras_for(volume, perspective=False))
    grid, cam = grid_of(volume), spec.camera()
    exact = render_xray_paper(grid, cam, method="exact", splat_kernel=kernel)
    if exact.max() <= 0:
        return
    error = max_error(render_xray_paper(grid, cam, method="regular", splat_kernel=kernel, antialias=False), exact)
    assert error <= REGULAR_TABLE[kernel], error


@PROPERTY
@given(st.data(), KERNELS)
def test_each_perspective_footprint_within_tolerance_of_its_peak(data, kernel):
    """One voxel seen from anywhere, inside the volume's box or out: its linearised footprint is
    within footprint_tolerance of its own peak, or it is splatted exactly."""
    volume = data.draw(volumes(max_side=3, single_voxel=True))
    spec = data.draw(st.one_of(cameras_for(volume, perspective=True), eyes_inside(volume)))
    grid, cam = grid_of(volume), spec.camera()
    exact = render_xray_paper(grid, cam, method="exact", splat_kernel=kernel).astype(np.float64)
    regular = render_xray_paper(grid, cam, method="regular", splat_kernel=kernel, antialias=False)
    peak = footprint_peaks(volume, spec, kernel)[0]
    assert np.abs(regular - exact).max() <= (FOOTPRINT_TOLERANCE + REGULAR_TABLE[kernel]) * peak


@PROPERTY
@given(st.data())
def test_pcvr_follows_its_model(data):
    """In perspective with exact footprints: the linearised ones are held to their peaks above."""
    volume = data.draw(volumes())
    spec = data.draw(cameras_for(volume))
    options = {} if spec.orthographic else {"footprint_tolerance": 0.0}
    error, stride = pcvr_model_error(grid_of(volume), spec, **options)
    assert error is None or error <= PHASE_TABLES, (error, stride)


@PROPERTY
@given(st.data())
def test_eye_inside_the_volume_with_exact_footprints(data):
    """With every footprint exact per ray (footprint_tolerance=0), regular is exact up to its table
    and pcvr its model, whatever the view from inside. The table is off by up to 2e-3 of a
    footprint's peak; seen from inside, an image may hold only footprints' rims (their peaks off the
    image, or their voxels behind the near plane), so the bound is 2e-3 of the sum of the peaks."""
    volume = data.draw(volumes())
    spec = data.draw(eyes_inside(volume))
    grid, cam = grid_of(volume), spec.camera()
    exact = render_xray_paper(grid, cam, method="exact").astype(np.float64)
    if exact.max() <= 0:
        return
    regular = render_xray_paper(grid, cam, method="regular", footprint_tolerance=0.0, antialias=False)
    assert np.abs(regular - exact).max() <= REGULAR_TABLE["gauss1.4"] * footprint_peaks(volume, spec, "gauss1.4").sum()
    error, stride = pcvr_model_error(grid, spec, footprint_tolerance=0.0)
    assert error is None or error <= PHASE_TABLES, (error, stride)


@PROPERTY
@given(st.data(), KERNELS, st.sampled_from(["bilinear", "gauss1.4", "gauss2.0"]))
def test_never_nan_and_the_same_for_any_thread_count(data, kernel, post):
    volume = data.draw(volumes())
    spec = data.draw(st.one_of(cameras_for(volume, max_magnification=64.0), eyes_inside(volume)))
    grid, cam = grid_of(volume), spec.camera()
    for method in METHODS:
        images = [render_xray_paper(grid, cam, method=method, splat_kernel=kernel, post_filter=post, threads=t)
                  for t in (1, 2, 0)]
        assert np.isfinite(images[0]).all(), method
        for image in images[1:]:
            np.testing.assert_array_equal(image, images[0], err_msg=method)
