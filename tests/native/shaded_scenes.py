"""Scenes for the shaded-rendering and MIP tests: small volumes, transfer functions, lights, and the
numbers the tests compare (PSNR, the optical depth behind an image's alpha)."""

from __future__ import annotations

import numpy as np

import pcvr_native as pn
from pcvr_native import phantoms

from conftest import frame_ortho, frame_perspective

# Light from the upper left, not along the view: shading shows the gradient's direction.
SUN = pn.Light.sun(direction=(-0.5, -0.2, -0.8))
VIEW = (0.3, -0.5, -0.8)


def ct_volume(n: int = 32) -> pn.Grid:
    """The CT-like head phantom: skull 1.0, brain 0.2, sharp-edged (one-voxel ramps)."""
    ph = phantoms.ct_phantom(n)
    return pn.Grid.from_dense(ph.values, ph.index_to_world)


def anisotropic_ct_volume(n: int = 32) -> pn.Grid:
    """The CT phantom sampled as scans often are, slices twice as far apart as pixels (1:1:2, like
    the CThead data set): half the slices over the same head."""
    full = phantoms.ct_phantom(n)
    values = np.ascontiguousarray(full.values[:, :, ::2])
    return pn.Grid.from_dense(values, phantoms.centred_transform(values.shape, (2.0 / n, 2.0 / n, 4.0 / n)))


def blob_volume(n: int = 24) -> pn.Grid:
    """Two overlapping Gaussian blobs: smooth, so that sheets and samples converge quickly."""
    c = (n - 1) / 2
    ph = phantoms.gaussian_blobs(n, [((c, c, c), n / 6, 1.0), ((c + n / 5, c, c - n / 6), n / 10, 0.8)])
    return pn.Grid.from_dense(ph.values, ph.index_to_world)


AIR = -1000.0
# Soft tissue (-100 to 100 HU) red and translucent, bone (from 600 HU) white; air and fat clear.
TISSUE_AND_BONE = pn.TransferFunction(
    density=[-3000, -300, -100, 100, 200, 600, 800, 3000],
    rgba=[[0.8, 0.2, 0.1, 0]] * 2 + [[0.8, 0.2, 0.1, 0.3]] * 2 + [[1, 1, 1, 0]] * 2 + [[1, 1, 1, 0.9]] * 2)


def heads_in_air(n: int = 32) -> tuple[pn.Grid, pn.Grid]:
    """A ball of soft tissue (40 HU, radius 9/32 of n) with a bone core (700 HU, 5/32 of n) in air, in Hounsfield
    units: air inactive at the background -1000 (sparse), and air active at -1000.001 (dense)."""
    i, j, k = np.mgrid[:n, :n, :n]
    c = (n - 1) / 2
    r = np.sqrt((i - c) ** 2 + (j - c) ** 2 + (k - c) ** 2)
    hu = np.where(r < 9 * n / 32, 40.0, AIR).astype(np.float32)
    hu[r < 5 * n / 32] = 700.0
    sparse = pn.Grid.from_dense(hu, np.eye(4), background=AIR)
    dense = pn.Grid.from_dense(np.where(hu == AIR, np.float32(AIR - 0.001), hu), np.eye(4), background=AIR)
    return sparse, dense


def bone_tf(unit_distance=None) -> pn.TransferFunction:
    """Transparent below 0.3, a reddish translucent ramp, opaque white at the skull's 1.0."""
    return pn.TransferFunction(density=[0.0, 0.3, 0.6, 1.0],
                               rgba=[[0, 0, 0, 0], [0.8, 0.4, 0.3, 0.0], [0.9, 0.8, 0.6, 0.4], [1, 1, 1, 0.9]],
                               unit_distance=unit_distance)


def optical_depth_tf(k: float, top: float, unit_distance: float = 0.05, points: int = 400) -> pn.TransferFunction:
    """White, with the opacity of a medium whose extinction is k * density (per world unit): opacity
    1 - exp(-k d u) of a slab u thick, sampled at `points` control points up to density `top` (piecewise
    linear in opacity, so the extinction is k d to within 1e-5 relative). Then -ln(1 - alpha) / k of a
    render is the line integral of the density: the X-ray image."""
    d = np.linspace(0.0, top, points)
    return pn.TransferFunction(density=d, rgba=[[1.0, 1.0, 1.0, a] for a in 1.0 - np.exp(-k * d * unit_distance)],
                               unit_distance=unit_distance)


def optical_depth(image: np.ndarray, k: float) -> np.ndarray:
    return -np.log1p(-np.asarray(image[..., 3], dtype=np.float64)) / k


def camera(grid, projection: str, magnification: float, direction=VIEW):
    frame = frame_ortho if projection == "ortho" else frame_perspective
    return frame(grid, magnification, direction=direction).camera()


def psnr(image, reference) -> float:
    """Peak signal-to-noise ratio in dB over premultiplied RGBA in [0, 1] (peak 1)."""
    mse = float(np.mean((np.asarray(image, dtype=np.float64) - np.asarray(reference, dtype=np.float64)) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(1.0 / mse)


def point_light(grid) -> pn.Light:
    """A point light up and to the left of the grid's centre, as bright there as the sun (strength 1)."""
    xf = np.asarray(grid.index_to_world)
    lo, hi = (np.asarray(b, dtype=np.float64) for b in grid.index_bbox)
    centre = xf[:3, :3] @ ((lo + hi) / 2) + xf[:3, 3]
    size = float(np.linalg.norm(xf[:3, :3] @ (hi - lo)))
    offset = np.array([-0.6, 0.8, 0.5]) * size
    return pn.Light.point(position=centre + offset, strength=float(offset @ offset))
