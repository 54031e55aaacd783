"""Scenes for the shadow and scattering tests: two blobs in a row along a sun's light, a slab of constant
extinction in front of a receiver, and the renders the tests compare (pcvr against the ray caster at the same
pixels)."""

from __future__ import annotations

import numpy as np

import pcvr_native as pn
from pcvr_native import phantoms

from shaded_scenes import camera

# Travels along +x, a little off the axis: the lattice's columns follow it, the grid's do not.
SUN_ALONG_X = pn.Light.sun(direction=(1.0, 0.15, -0.1))
# From above the view: the blobs side by side, both in sight.
VIEW_FROM_ABOVE = (0.2, -0.3, -1.0)
NEAR_CENTRE, FAR_CENTRE = (11, 10, 10), (28, 10, 10)
GREY = pn.TransferFunction(density=[0.0, 0.2, 1.0], rgba=[[1, 1, 1, 0], [1, 1, 1, 0.05], [1, 1, 1, 0.5]])
# The ray caster's step (voxels) for views and shadow rays, and every how many pixels it renders: 0.25 and
# 0.1 agree to 54-72 dB on these scenes with shadows (0.1 takes three times as long).
REFERENCE_SPACING, REFERENCE_STEP = 0.25, 3


def blobs(centres=(NEAR_CENTRE, FAR_CENTRE), sigma: float = 3.0) -> pn.Grid:
    """Gaussian blobs of peak 1 in a 40 x 20 x 20 grid (world = index): by default one at x = 11, the light's
    side, and one at x = 28 in its shadow."""
    ph = phantoms.gaussian_blobs((40, 20, 20), [(c, sigma, 1.0) for c in centres])
    return pn.Grid.from_dense(ph.values, ph.index_to_world)


def blob_camera(grid: pn.Grid, projection: str = "ortho", magnification: float = 2.0):
    return camera(grid, projection, magnification, direction=VIEW_FROM_ABOVE)


def pixel_mask(grid: pn.Grid, cam, step: int = 1) -> np.ndarray:
    """The pixels where `grid` alone is more than half opaque (every step-th)."""
    alone = pn.render_shaded(grid, cam, GREY, lights=[], opacity_cutoff=1.0)
    return alone[::step, ::step, 3] > 0.5


def pcvr_and_reference(grid, cam, tf, lights, **kwargs) -> tuple[np.ndarray, np.ndarray]:
    """pcvr's image at the ray caster's pixels, and the ray caster's."""
    image = pn.render_shaded(grid, cam, tf, lights=lights, opacity_cutoff=1.0, **kwargs)
    reference = pn.render_shaded(grid, cam, tf, lights=lights, method="raycast", sheet_spacing=REFERENCE_SPACING,
                                 pixel_step=REFERENCE_STEP, opacity_cutoff=1.0, **kwargs)
    return image[::REFERENCE_STEP, ::REFERENCE_STEP], reference


def slab_and_receiver(k: float, density: float, thickness: int, receiver: bool = True, slab: bool = True) -> pn.Grid:
    """A slab of constant density `thickness` voxels thick across x = 4.. (the caster), and a cube of density
    0.5 at x = 24..29 (the receiver), in a 36 x 24 x 24 grid (world = index). Under optical_depth_tf(k) a light
    along +x crosses the whole slab on its way to the receiver: optical depth k * density * thickness."""
    values = np.zeros((36, 24, 24), dtype=np.float32)
    if slab:
        values[4:4 + thickness, :, :] = density
    if receiver:
        values[24:30, 9:15, 9:15] = 0.5
    return pn.Grid.from_dense(values, np.eye(4))


def half_caster_and_receiver() -> pn.Grid:
    """A slab of density 1 across x = 4..7 covering y < 16 only (the caster: its shadow has an edge), and a box of
    density 0.5 at x = 26..31 beyond it, in a 40 x 32 x 24 grid (world = index). A sun along +x."""
    values = np.zeros((40, 32, 24), dtype=np.float32)
    values[4:8, :16, :] = 1.0
    values[26:32, 4:28, 4:20] = 0.5
    return pn.Grid.from_dense(values, np.eye(4))
