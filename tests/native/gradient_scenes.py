"""Scenes for the gradient-opacity tests: a linear ramp whose gradient magnitude is known in world units,
seen along its gradient, and the opacity a ray through it should reach."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import pcvr_native as pn
from pcvr_native import phantoms

from xray_helpers import frame_ortho, frame_perspective, rotation


@dataclass
class Ramp:
    """density = slope * (signed world distance along `axis` from the ramp's zero), in a box of voxels."""
    grid: pn.Grid
    slope: float       # |grad density|, density units per world unit
    axis: np.ndarray   # world direction of the gradient (index axis i)
    band: tuple        # (low, high): the transfer function is opaque for densities in between


def ramp(slope: float = 3.0, spacing=(0.5, 0.8, 0.35), shape=(24, 10, 12), band=(1.5, 7.5)) -> Ramp:
    """A linear ramp along index i under an anisotropic, rotated index-to-world transform: voxel spacing 0.5
    along the ramp, so `slope` per world unit is slope * 0.5 per index step. Its zero lies between voxel
    centres (no voxel equals the background 0), in the middle. The band lies near the zero, where the Gaussian
    kernels' reconstruction (not quite a partition of unity: a ripple in proportion to the value) departs
    least from the ramp, and above the densities where the box's sides fall off to the background gently."""
    linear = rotation((1.0, 2.0, 3.0), 0.7)
    i = np.arange(shape[0], dtype=np.float64) - (shape[0] - 1) / 2
    values = np.broadcast_to((slope * spacing[0] * i)[:, None, None], shape).astype(np.float32)
    grid = pn.Grid.from_dense(np.ascontiguousarray(values), phantoms.centred_transform(shape, spacing, linear))
    return Ramp(grid, slope, linear[:, 0], band)


def band_tf(band, opacity: float, unit_distance: float, **gradient_opacity) -> pn.TransferFunction:
    """White with opacity `opacity` for densities in band = (low, high), transparent outside (sharp edges)."""
    low, high = band
    edge = 1e-3 * (high - low)
    return pn.TransferFunction(density=[low - edge, low, high, high + edge],
                               rgba=[[1, 1, 1, 0], [1, 1, 1, opacity], [1, 1, 1, opacity], [1, 1, 1, 0]],
                               unit_distance=unit_distance, **gradient_opacity)


def ramp_camera(scene: Ramp, projection: str) -> pn.Camera:
    """A camera looking along the ramp's gradient at its centre: the middle pixels' rays cross the band
    ((high - low) / slope world units long) and no side of the box."""
    frame = frame_ortho if projection == "ortho" else frame_perspective
    up = np.cross(scene.axis, (0.3, 0.9, 0.1))
    return frame(scene.grid, 3.0, direction=scene.axis, up=up).camera()


def band_alpha(scene: Ramp, opacity: float, factor: float, unit_distance: float) -> float:
    """The alpha of a ray along the gradient: the band's length in unit distances, each of opacity
    opacity * factor."""
    length = (scene.band[1] - scene.band[0]) / scene.slope
    return 1.0 - (1.0 - opacity * factor) ** (length / unit_distance)


def middle(image: np.ndarray, half: int = 1) -> np.ndarray:
    """The (2 half + 1)^2 pixels around the middle of an image."""
    r, c = image.shape[0] // 2, image.shape[1] // 2
    return image[r - half:r + half + 1, c - half:c + half + 1]
