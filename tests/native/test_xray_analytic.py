"""The renderer against truths computed without it.

1. `exact` against conftest.reference_xray: the same line integrals written independently in numpy
   (double precision, footprint from phantoms.kernel_line_integral), on tiny volumes: they must agree to
   float32 output rounding.
2. Sampled Gaussian blobs against the closed form of phantoms.gaussian_blobs_xray (a Gaussian of variance
   sigma^2 + s_k^2 per blob). The closed form is not exact for the reconstructed volume: it leaves out
   (a) the lattice ripple of the kernel, a relative modulation of at most sum_k |h^(k)| over the
   non-zero integer frequencies k (0.25% for gauss1.4, 2.9% for gauss2.0, see the slab test), damped by
   exp(-2 pi^2 (sigma^2 + s_k^2) (k.e)^2) along a ray of index-space direction e, and (b) the kernel's
   non-Gaussian cumulants, O(kappa_4 / (8 (sigma^2 + s_k^2)^2)) ~ 1e-3. Measured against the numpy
   reference (test_closed_form_against_reference): <= 1.3e-3 of the peak for gauss1.4 and
   <= 1e-3 for gauss2.0 at the oblique views used here; tolerances are 2.5x that.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import pcvr_native as pn
from pcvr_native import phantoms

from conftest import (KERNELS, LINEAR_PARTS, frame_ortho, frame_perspective, predict_bilinear_spread, predict_pcvr, reference_xray,
                      regular_tolerance, rel_rmse, render)

# Max |closed form - truth| relative to the image's peak, per kernel (see the module docstring).
CLOSED_FORM_TOL = {"gauss1.4": 3.5e-3, "gauss2.0": 5e-3, "linear": 4e-2}

N_BLOB = 22
BLOBS = [((10.3, 11.1, 10.6), 1.5, 1.0), ((9.0, 12.5, 11.5), 1.8, 0.5), ((12.2, 9.4, 9.0), 1.6, -0.3)]
VIEW = (0.3, -0.5, -1.0)


def blob_setup(lin: str, proj: str, mag: float = 2.0):
    xf = phantoms.centred_transform((N_BLOB,) * 3, 0.8, LINEAR_PARTS[lin])
    ph = phantoms.gaussian_blobs(N_BLOB, BLOBS, xf)
    if proj == "ortho":
        cam = frame_ortho(ph, mag, VIEW, offset=(0.21, 0.37))
    else:
        cam = frame_perspective(ph, mag, VIEW, distance=3.5)
    return ph, cam


def closed_form(cam, xf, kernel):
    return phantoms.gaussian_blobs_xray(BLOBS, (cam.world_to_camera, cam.projection, cam.width, cam.height), xf,
                                        kernel)


@pytest.mark.parametrize("kernel", KERNELS)
@pytest.mark.parametrize("lin,proj", [("sheared", "ortho"), ("mirrored", "persp"), ("scaled", "ortho"),
                                      ("rotated", "persp")])
def test_exact_matches_numpy_reference(kernel, lin, proj, rng):
    values = (rng.random((6, 7, 5)) + 0.2).astype(np.float32)
    values[rng.random(values.shape) < 0.2] = 0.0
    xf = phantoms.centred_transform(values.shape, 0.7, LINEAR_PARTS[lin])
    xf[:3, 3] += (0.3, -0.2, 0.1)
    grid = pn.Grid.from_dense(values, xf)
    cam = (frame_ortho((values, xf), 2.7, (0.4, -0.3, -1.0)) if proj == "ortho"
           else frame_perspective((values, xf), 2.7, (0.4, -0.3, -1.0), distance=2.5))
    ref = reference_xray(values, xf, cam, kernel)
    img = render(grid, cam, "exact", kernel)
    err = np.abs(img - ref).max() / np.abs(ref).max()
    assert err < 1e-6, f"exact vs numpy reference: max error {err:.2e} of the peak"


def test_exact_pixel_step_is_a_subsample(rng):
    values = (rng.random((6, 6, 6)) + 0.2).astype(np.float32)
    xf = phantoms.centred_transform(values.shape, 0.7, LINEAR_PARTS["rotated"])
    grid = pn.Grid.from_dense(values, xf)
    cam = frame_ortho((values, xf), 3.0, (0.4, -0.3, -1.0))
    full = render(grid, cam, "exact")
    step = np.asarray(pn.render_xray(grid, cam.camera(), "exact", pixel_step=7), dtype=np.float64)
    np.testing.assert_array_equal(step, full[::7, ::7])


def test_closed_form_against_reference():
    """phantoms.gaussian_blobs_xray itself, against the numpy line integrals (no renderer involved)."""
    for lin, proj in [("identity", "ortho"), ("sheared", "persp")]:
        ph, cam = blob_setup(lin, proj, mag=1.5)
        for kernel in ("gauss1.4", "gauss2.0"):
            ref = reference_xray(ph.values, ph.index_to_world, cam, kernel)
            cf = closed_form(cam, ph.index_to_world, kernel)
            err = np.abs(cf - ref).max() / np.abs(ref).max()
            assert err < CLOSED_FORM_TOL[kernel], f"{lin}/{proj}/{kernel}: {err:.2e}"


@pytest.mark.parametrize("kernel", ["gauss1.4", "gauss2.0", "linear"])
@pytest.mark.parametrize("method", ["exact", "regular"])
@pytest.mark.parametrize("lin,proj", [("identity", "ortho"), ("sheared", "ortho"), ("identity", "persp"),
                                      ("sheared", "persp")])
def test_blobs_match_closed_form(method, kernel, lin, proj):
    ph, cam = blob_setup(lin, proj)
    img = render(ph.grid(), cam, method, kernel)
    cf = closed_form(cam, ph.index_to_world, kernel)
    tol = CLOSED_FORM_TOL[kernel] + (regular_tolerance(ph.values, ph.index_to_world, cam) if method == "regular" else 0)
    err = np.abs(img - cf).max() / np.abs(cf).max()
    assert err < tol, f"{method}/{kernel}/{lin}/{proj}: max error {err:.2e} of the peak >= {tol:.1e}"
    # The integral of the image is the blobs' total mass (orthographic only: it is what the image plane sees).
    if proj == "ortho":
        px, py = cam.pixel_size
        det = abs(np.linalg.det(ph.index_to_world[:3, :3]))
        mass = sum(a * (2 * math.pi * s * s) ** 1.5 for _, s, a in BLOBS) * det
        assert img.sum() * px * py == pytest.approx(mass, rel=1e-3)


@pytest.mark.parametrize("post", ["bilinear", "gauss1.4", "gauss2.0"])
@pytest.mark.parametrize("lin,proj,mag,stride", [("identity", "ortho", 4.0, 4), ("sheared", "ortho", 3.0, 3),
                                                 ("sheared", "persp", 3.0, 2)])
def test_pcvr_blobs_match_post_convolved_closed_form(post, lin, proj, mag, stride):
    """pcvr is the closed form sampled at the subgrid nodes and post-convolved (numpy model)."""
    ph, cam = blob_setup(lin, proj, mag)
    pad = 2 * stride
    model = predict_pcvr(closed_form(cam.padded(pad), ph.index_to_world, "gauss1.4"), pad, stride, post,
                         cam.height, cam.width)
    img = render(ph.grid(), cam, "pcvr", "gauss1.4", post, stride)
    tol = CLOSED_FORM_TOL["gauss1.4"] + regular_tolerance(ph.values, ph.index_to_world, cam)
    err = np.abs(img - model).max() / np.abs(model).max()
    assert err < tol, f"pcvr/{post}/{lin}/{proj}: max error {err:.2e} of the peak >= {tol:.1e}"
    # And the post-filter's blur is visible: pcvr differs from the unfiltered closed form by more.
    cf = closed_form(cam, ph.index_to_world, "gauss1.4")
    assert rel_rmse(img, cf) > rel_rmse(img, model)


@pytest.mark.parametrize("kernel", KERNELS)
def test_kernel_info_matches_closed_forms(kernel):
    """Radius, per-axis variance and central line integral (i.e. the normalisation) in closed form
    (phantoms: erf for the Gaussians, polynomials for linear and box)."""
    info = pn.kernel_info(kernel)
    _, radius, _ = phantoms.kernel_profile(kernel)
    assert info["radius"] == pytest.approx(radius, rel=1e-12)
    assert info["variance"] == pytest.approx(phantoms.kernel_variance(kernel), rel=1e-9)
    assert info["line_integral_at_centre"] == pytest.approx(float(phantoms.kernel_line_integral(kernel, 0.0)), rel=1e-9)


@pytest.mark.parametrize("proj", ["ortho", "persp"])
def test_clipping_is_per_voxel(proj, rng):
    """Near and far planes through the volume drop the voxels whose centres lie outside them, whole
    (their footprints are not cut): the numpy reference applies the same rule."""
    values = (rng.random((8, 8, 8)) + 0.2).astype(np.float32)
    xf = phantoms.centred_transform(values.shape, 0.5, LINEAR_PARTS["rotated"])
    grid = pn.Grid.from_dense(values, xf)
    cam = (frame_ortho((values, xf), 3.0, (0.2, -0.3, -1.0)) if proj == "ortho"
           else frame_perspective((values, xf), 3.0, (0.2, -0.3, -1.0), distance=3.0))
    # Depth of the volume centre along the view, then planes 1.1 voxels in front of and behind it.
    centre_depth = -(cam.world_to_camera @ np.r_[xf[:3, 3] + xf[:3, :3] @ np.full(3, 3.5), 1.0])[2]
    near, far = centre_depth - 0.55, centre_depth + 0.55
    p = cam.projection.copy()
    p[2, 2] = -(far + near) / (far - near)  # perspective; the orthographic row is set below
    if proj == "ortho":
        p[2, 2], p[2, 3] = -2.0 / (far - near), -(far + near) / (far - near)
    else:
        # Only the depth row changes: x and y of a perspective projection do not depend on near/far.
        p[2, 3] = -2.0 * far * near / (far - near)
    clipped = type(cam)(cam.world_to_camera, p, cam.width, cam.height)
    ref = reference_xray(values, xf, clipped)
    full = reference_xray(values, xf, cam)
    assert 0.2 < np.abs(ref).sum() / np.abs(full).sum() < 0.8  # the planes did cut the volume
    exact = render(grid, clipped, "exact")
    np.testing.assert_allclose(exact, ref, rtol=1e-5, atol=1e-6 * np.abs(ref).max())
    regular = render(grid, clipped, "regular")
    tol = regular_tolerance(values, xf, cam) * np.abs(ref).max()
    assert np.abs(regular - ref).max() < tol
    # pcvr: the clipped reference sampled at its subgrid nodes and post-convolved.
    stride, pad = 3, 6
    model = predict_pcvr(reference_xray(values, xf, clipped.padded(pad)), pad, stride, "bilinear", cam.height, cam.width)
    assert np.abs(render(grid, clipped, "pcvr", stride=stride) - model).max() < tol
    if proj == "ortho":  # bilinear spreading's model, of the voxels the planes keep
        clip = (np.c_[np.argwhere(np.ones(values.shape)), np.ones(values.size)] @ xf.T) @ (p @ cam.world_to_camera).T
        kept = np.where(((np.abs(clip[:, 2]) <= clip[:, 3]) & (clip[:, 3] > 0)).reshape(values.shape), values, 0)
        model = predict_bilinear_spread(kept, xf, clipped, stride, "bilinear")
        spread = render(grid, clipped, "bilinear_spread", stride=stride)
        np.testing.assert_allclose(spread, model, rtol=1e-4, atol=1e-5 * np.abs(model).max())


@pytest.mark.parametrize("proj", ["ortho", "persp"])
def test_off_axis_projection(proj, rng):
    """A shifted window (Blender's lens shift): an asymmetric frustum or ortho box."""
    values = (rng.random((6, 6, 6)) + 0.2).astype(np.float32)
    xf = phantoms.centred_transform(values.shape, 0.5, LINEAR_PARTS["sheared"])
    grid = pn.Grid.from_dense(values, xf)
    cam = (frame_ortho((values, xf), 3.0, (0.2, -0.3, -1.0), margin=10) if proj == "ortho"
           else frame_perspective((values, xf), 3.0, (0.2, -0.3, -1.0), distance=3.0, margin=10))
    cam = cam.shifted(7.3, -4.6)
    ref = reference_xray(values, xf, cam)
    np.testing.assert_allclose(render(grid, cam, "exact"), ref, rtol=1e-5, atol=1e-6 * np.abs(ref).max())
    tol = regular_tolerance(values, xf, cam)
    assert np.abs(render(grid, cam, "regular") - ref).max() < tol * np.abs(ref).max()


def test_phantom_generators():
    """The generators' promises: shapes, dtypes, ranges, sparsity; Marschner-Lobb at a known point."""
    ct = phantoms.ct_phantom(48)
    assert ct.values.shape == (48,) * 3 and ct.values.dtype == np.float32
    assert ct.values.min() >= 0.0 and ct.values.max() == pytest.approx(1.0, abs=1e-6)
    assert 0.2 < np.mean(ct.values > 0) < 0.35  # the head ellipsoid fills ~27% of [-1, 1]^3
    assert ct.values[24, 24, 24] == pytest.approx(0.2, abs=1e-6)  # brain: 1.0 - 0.8
    ml = phantoms.marschner_lobb(41)
    # rho(0, 0, 0) = (1 + alpha (1 + cos(2 pi f_M))) / (2 (1 + alpha)) = (1 + 0.5) / 2.5
    assert ml.values[20, 20, 20] == pytest.approx(0.6, abs=1e-6)
    assert ml.index_to_world[0, 0] == pytest.approx(0.05) and ml.index_to_world[0, 3] == pytest.approx(-1.0)
    cloud = phantoms.sparse_cloud(32, seed=4)
    assert 0.12 < np.mean(cloud.values > 0) < 0.18 and cloud.values.max() == pytest.approx(1.0)
    dense = phantoms.dense_volume(16, seed=4)
    assert dense.values.min() >= 0.6 - 1e-6 and dense.values.max() <= 1.4 + 1e-6
    np.testing.assert_array_equal(phantoms.sparse_cloud(32, seed=4).values, cloud.values)  # seeded
    assert ct.grid().active_voxel_count == int(np.count_nonzero(ct.values))


def test_closed_form_accepts_a_camera():
    ph, cam = blob_setup("sheared", "persp")
    np.testing.assert_allclose(phantoms.gaussian_blobs_xray(BLOBS, cam.camera(), ph.index_to_world, "gauss1.4"),
                               closed_form(cam, ph.index_to_world, "gauss1.4"), rtol=1e-12)
