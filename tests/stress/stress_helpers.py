"""Helpers for the stress suite: how long to run, scenes placed at any scale and offset, and error
measures. `make test` runs the quick selection; `make stress` sets PCVR_STRESS=long for more cases,
larger volumes and more Hypothesis examples.
"""

from __future__ import annotations

import os

import numpy as np

import pcvr_native as pn
from pcvr_native import cameras
from sanitized import measures_memory  # noqa: F401  (the stress tests take it from here)

LONG = os.environ.get("PCVR_STRESS") == "long"

SPLAT_METHODS = ("regular", "pcvr", "bilinear_spread")
METHODS = ("exact",) + SPLAT_METHODS


def max_error(image, reference) -> float:
    """Largest absolute difference relative to the reference's largest magnitude."""
    image, reference = np.asarray(image, np.float64), np.asarray(reference, np.float64)
    return float(np.abs(image - reference).max() / np.abs(reference).max())


def resolution_in_voxels(offset, voxel: float) -> float:
    """How finely double precision resolves positions `offset` world units out, in voxels `voxel` wide."""
    return float(np.abs(offset).max()) * np.finfo(float).eps / voxel


def placed(scale: float, offset) -> np.ndarray:
    """World transform that scales about the origin by `scale`, then moves by `offset`."""
    m = np.diag([scale, scale, scale, 1.0])
    m[:3, 3] = offset
    return m


def scene_camera(scale: float, offset, perspective: bool, width: int = 48, height: int = 48, eye=(3.0, -5.0, 30.0),
                 target=(0.0, 0.0, 0.0), half: float = 10.0, near: float = 5.0, far: float = 100.0) -> pn.Camera:
    """A camera looking at `target` from `eye` (unit-scale world), placed like placed(scale, offset):
    a rigid view, and a projection whose window and clip range scale with the scene, so that the
    image is the unit image times `scale` (a line integral is density times world length)."""
    # The view's rotation from the unit-scale geometry (1e8 out, eye - target would round), its
    # translation from where the eye is.
    w2c = cameras.look_at(eye, target, (0.0, 0.0, 1.0))
    w2c[:3, 3] = -w2c[:3, :3] @ (np.asarray(eye) * scale + np.asarray(offset, dtype=np.float64))
    if perspective:
        projection = cameras.perspective(2.0 * np.arctan(half / np.linalg.norm(np.subtract(eye, target))), width / height,
                                         near * scale, far * scale)
    else:
        projection = cameras.ortho(-half * scale, half * scale, -half * scale * height / width, half * scale * height / width,
                                   near * scale, far * scale)
    return pn.Camera(w2c, projection, width, height)
