"""Shared helpers for the native X-ray tests: an independent numpy reference and the numpy model of
PCVR's post-convolution. Cameras, framing and transforms live in tests/xray_helpers.py (shared with
the stress tests) and are re-exported here.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pcvr_native import phantoms

KERNELS = ("gauss1.4", "gauss2.0", "linear", "box")
POST_FILTERS = ("bilinear", "gauss1.4", "gauss2.0")


@pytest.fixture
def rng():
    return np.random.default_rng(20240607)


from pcvr_native.cameras import frustum, look_at, ortho, perspective  # noqa: E402,F401
from xray_helpers import (  # noqa: E402,F401  (the tests import these from here)
    LINEAR_PARTS, CameraSpec, frame_ortho, frame_perspective, kernel_variance, min_singular, post_matrix, post_weight,
    predict_pcvr, rel_rmse, render, rotation, volume_parts)


def image_mass(img, cam: CameraSpec) -> float:
    """Integral of an orthographic image over the image plane, world units."""
    px, py = cam.pixel_size
    return float(np.sum(img, dtype=np.float64) * px * py)


def volume_mass(values, xf) -> float:
    return float(np.sum(values, dtype=np.float64) * abs(np.linalg.det(np.asarray(xf)[:3, :3])))


# How far `regular` may be from `exact` (relative RMSE, and max error relative to the peak):
# * the footprint table: 4096 nearest samples in rho^2 over [0, R^2]; for F ~ exp(-a rho^2) one tap is
#   off by at most a R^2 / 4096 / 2 = 6.8e-4 (gauss1.4), 9.8e-4 (gauss2.0) of itself, and all taps are
#   positive, so no pixel is off by more: 2e-3 leaves 2x (measured 3e-5..2e-4 RMSE, orthographic).
# * perspective: each voxel's footprint is the projection linearised at its centre; the true one differs
#   at second order in (kernel radius / depth) (measured 0.75-0.85 (R / d)^2 relative).
REGULAR_TOL = 2e-3


def regular_tolerance(values, xf, cam: "CameraSpec", radius: float = 2.0) -> float:
    if cam.orthographic:
        return REGULAR_TOL
    xf = np.asarray(xf, dtype=np.float64)
    idx = np.argwhere(np.asarray(values) != 0).astype(np.float64)
    world = idx @ xf[:3, :3].T + xf[:3, 3]
    depth = -(world @ cam.world_to_camera[2, :3] + cam.world_to_camera[2, 3])
    r_world = radius * float(np.linalg.svd(xf[:3, :3], compute_uv=False).max())
    return REGULAR_TOL + (r_world / float(depth.min())) ** 2


# --------------------------------------------------------------------------------------------
# Independent reference: the analytic line integral of every voxel's kernel along every pixel ray,
# in numpy (double). Only for tiny volumes: cost is voxels x pixels.

def reference_xray(values, xf, cam: CameraSpec, kernel: str = "gauss1.4", chunk: int = 128) -> np.ndarray:
    values = np.asarray(values)
    xf = np.asarray(xf, dtype=np.float64)
    idx = np.argwhere(values != 0).astype(np.float64)
    v = values[values != 0].astype(np.float64)
    # Per-voxel clipping: the centre must lie between near and far (-w <= z <= w, w > 0).
    clip = (np.c_[idx, np.ones(len(idx))] @ xf.T) @ (cam.projection @ cam.world_to_camera).T
    keep = (clip[:, 3] > 0) & (clip[:, 2] >= -clip[:, 3]) & (clip[:, 2] <= clip[:, 3])
    idx, v = idx[keep], v[keep]
    origins, dirs = phantoms.pixel_rays((cam.world_to_camera, cam.projection, cam.width, cam.height))
    b = np.linalg.inv(xf)
    u0 = (origins.reshape(-1, 3) @ b[:3, :3].T + b[:3, 3])        # ray origins in index space
    e = dirs.reshape(-1, 3) @ b[:3, :3].T                          # index units per world unit
    e_len = np.linalg.norm(e, axis=1)
    e_unit = e / e_len[:, None]
    footprint = _footprint_interpolant(kernel)
    out = np.zeros(len(u0))
    for s in range(0, len(idx), chunk):
        diff = u0[:, None, :] - idx[None, s:s + chunk, :]
        along = np.einsum("pnk,pk->pn", diff, e_unit)
        rho2 = np.maximum(np.einsum("pnk,pnk->pn", diff, diff) - along * along, 0.0)
        out += footprint(rho2) @ v[s:s + chunk]
    return (out / e_len).reshape(cam.height, cam.width)


_FOOTPRINTS = {}


def _footprint_interpolant(kernel: str):
    """rho^2 -> footprint. The Gaussians (erf) through a 2^21-entry table in rho (linear interpolation
    error < 2e-8 of the peak); linear and box in closed form."""
    if not kernel.startswith("gauss"):
        return lambda rho2: phantoms.kernel_line_integral(kernel, np.sqrt(rho2))
    if kernel not in _FOOTPRINTS:
        rho = np.linspace(0.0, 2.0, 2 ** 21 + 1)
        _FOOTPRINTS[kernel] = (rho, phantoms.kernel_line_integral(kernel, rho))
    rho, table = _FOOTPRINTS[kernel]
    return lambda rho2: np.interp(np.sqrt(rho2), rho, table, right=0.0)


# --------------------------------------------------------------------------------------------
# More of PCVR's second stage in numpy (post_weight, post_matrix and predict_pcvr are in
# tests/xray_helpers.py).

def pixel_moments(post: str, stride: float, pixels: int):
    """First and second moments (pixels, pixels^2) of the node offsets of pixels 0 .. pixels - 1, for
    nodes `stride` pixels apart (whole or not: node n sits on pixel stride * n)."""
    x = np.arange(pixels, dtype=np.float64)[:, None]
    node = np.floor(x / stride) + np.arange(-4, 5)[None, :]
    delta = stride * node - x  # node minus pixel
    w = post_weight(post, delta / stride)
    w /= w.sum(axis=1, keepdims=True)
    return np.sum(w * delta, axis=1), np.sum(w * delta * delta, axis=1)


def project_to_pixels(points_world: np.ndarray, cam: CameraSpec) -> np.ndarray:
    """Continuous pixel coordinates (column, row from the top; pixel centres at integers) of points."""
    clip = np.c_[points_world, np.ones(len(points_world))] @ (cam.projection @ cam.world_to_camera).T
    ndc = clip[:, :2] / clip[:, 3:4]
    return np.c_[(ndc[:, 0] + 1.0) * 0.5 * cam.width - 0.5, (1.0 - ndc[:, 1]) * 0.5 * cam.height - 0.5]


def predict_bilinear_spread(values, xf, cam: CameraSpec, stride: int, post: str) -> np.ndarray:
    """bilinear_spread for an orthographic camera, in numpy: each voxel's footprint mass, in image units
    times subgrid cells (v |det A| / (pixel area L^2)), goes to the 2x2 nodes around its projected centre
    with bilinear weights; then the post-filter, as in predict_pcvr."""
    values = np.asarray(values)
    idx = np.argwhere(values != 0).astype(np.float64)
    v = values[values != 0].astype(np.float64)
    px, py = cam.pixel_size
    mass = v * abs(np.linalg.det(np.asarray(xf)[:3, :3])) / (px * py * stride * stride)
    pix = project_to_pixels(idx @ np.asarray(xf)[:3, :3].T + np.asarray(xf)[:3, 3], cam) / stride
    base = np.floor(pix).astype(int)
    frac = pix - base
    lo = base.min(axis=0) - 3
    hi = base.max(axis=0) + 4
    lo = np.minimum(lo, (-2, -2))
    hi = np.maximum(hi, ((cam.width - 1) // stride + 3, (cam.height - 1) // stride + 3))
    nodes = np.zeros((hi[1] - lo[1], hi[0] - lo[0]))  # [row node, column node]
    for dx in (0, 1):
        for dy in (0, 1):
            w = (frac[:, 0] if dx else 1.0 - frac[:, 0]) * (frac[:, 1] if dy else 1.0 - frac[:, 1])
            np.add.at(nodes, (base[:, 1] + dy - lo[1], base[:, 0] + dx - lo[0]), mass * w)
    nodes_x = np.arange(lo[0], hi[0])
    nodes_y = np.arange(lo[1], hi[1])
    return post_matrix(post, stride, cam.height, nodes_y) @ nodes @ post_matrix(post, stride, cam.width, nodes_x).T


def kernel_spectrum(kernel: str, f) -> np.ndarray:
    """3-D Fourier transform of the normalised kernel at radial frequency f (cycles per index unit):
    4 pi integral h(r) r^2 sinc(2 f r) dr, midpoint rule on 20000 nodes (> 100 per oscillation up to
    f = 50; error < 1e-6)."""
    raw, radius, norm = phantoms.kernel_profile(kernel)
    n = 20000
    r = (np.arange(n) + 0.5) * (radius / n)
    weight = raw(r) * 4.0 * math.pi * r * r * (radius / n) * norm
    f = np.asarray(f, dtype=np.float64)
    return (np.sinc(2.0 * f.reshape(-1, 1) * r[None, :]) @ weight).reshape(f.shape)


def sampling_mass_error(kernel: str, values, xf, cam: CameraSpec, spacing_px: float, kmax: int = 8) -> float:
    """Expected relative error of summing an orthographic image on a lattice of `spacing_px` pixels
    instead of integrating it. By Poisson summation one voxel's error is sum over lattice frequencies
    k != 0 of the kernel's spectrum at the index-space frequency J^T k / spacing (J: pixels per index
    unit) times a phase factor; over voxels at unrelated sub-pixel phases these add like random
    numbers: sqrt(sum_k spectrum^2) * sqrt(sum v^2) / sum v. (Coherent phases could reach
    sum_k |spectrum|, which the truncated kernels' slowly decaying tails make useless as a bound.)"""
    px, py = cam.pixel_size
    jac = np.diag([1.0 / px, 1.0 / py]) @ cam.world_to_camera[:2, :3] @ np.asarray(xf)[:3, :3]
    ks = np.array([(a, b) for a in range(-kmax, kmax + 1) for b in range(-kmax, kmax + 1) if (a, b) != (0, 0)], float)
    q = np.linalg.norm((ks / spacing_px) @ jac, axis=1)
    v = np.asarray(values, dtype=np.float64)
    v = v[v != 0]
    return float(np.sqrt(np.sum(kernel_spectrum(kernel, q) ** 2)) * np.sqrt(np.sum(v * v)) / abs(np.sum(v)))


def taylor_pcvr_error(image: np.ndarray, stride: float, post: str) -> np.ndarray:
    """Second-order Taylor estimate of pcvr - image for a smooth image (pixel units).

    Output pixel p is sum_n w_n E(p + delta_n) over nodes at offsets delta_n, so
    pcvr - E ~ m1x Ex + m1y Ey + (m2x Exx + m2y Eyy) / 2 + m1x m1y Exy with the per-phase moments
    m1 = sum w delta, m2 = sum w delta^2 of each axis (the filter is separable). For bilinear m1 = 0
    and m2 = L^2 t (1 - t) at phase t (the pixel's fraction of a node); for the Gaussians m2 ~ L^2 / (2 a) at every phase.
    """
    h, w = image.shape
    m1x, m2x = (m[None, :] for m in pixel_moments(post, stride, w))
    m1y, m2y = (m[:, None] for m in pixel_moments(post, stride, h))
    ey, ex = np.gradient(image)
    exx = np.zeros_like(image)
    eyy = np.zeros_like(image)
    exx[:, 1:-1] = image[:, 2:] - 2 * image[:, 1:-1] + image[:, :-2]
    eyy[1:-1, :] = image[2:, :] - 2 * image[1:-1, :] + image[:-2, :]
    exy = np.gradient(ex, axis=0)
    # Rows grow downwards in both the image and the node offsets, so no sign flips are needed.
    return m1x * ex + m1y * ey + 0.5 * (m2x * exx + m2y * eyy) + m1x * m1y * exy
