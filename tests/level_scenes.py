"""The scenes the shaded levels of detail are measured on (tests/bench/shaded_levels.py) and tested with
(tests/native/test_shaded_levels.py): the test pins numbers the benchmark measured on the same volume."""

from __future__ import annotations

import numpy as np

import pcvr_native as pn
from pcvr_native import phantoms

# Translucent blue at 0.2, orange at 0.5, opaque white at 1.
TRANSLUCENT = pn.TransferFunction(density=[0.0, 0.2, 0.5, 1.0],
                                  rgba=[[0, 0, 0, 0], [0.2, 0.4, 0.9, 0.05], [0.9, 0.6, 0.2, 0.3], [1, 1, 1, 0.8]])


def scattered_blobs(n: int = 64) -> pn.Grid:
    """Eight Gaussian blobs of 3% to 12% of n in radius, of densities 0.4 to 1, in the middle half of an n^3
    grid (seeded)."""
    rng = np.random.default_rng(7)
    spec = [(tuple(rng.uniform(0.25 * n, 0.75 * n, 3)), float(rng.uniform(0.03, 0.12) * n),
             float(rng.uniform(0.4, 1.0))) for _ in range(8)]
    ph = phantoms.gaussian_blobs(n, spec)
    return pn.Grid.from_dense(ph.values, ph.index_to_world)


def pixel_means(render, camera, factor: int = 4) -> np.ndarray:
    """What a minified image's pixels should show: `render(camera)` at `factor` x `factor` times the pixels,
    each block of factor x factor averaged (premultiplied RGBA averages as the light does)."""
    fine = pn.Camera(camera.world_to_camera, camera.projection, factor * camera.width, factor * camera.height)
    image = np.asarray(render(fine), np.float64)
    return image.reshape(camera.height, factor, camera.width, factor, -1).mean(axis=(1, 3))
