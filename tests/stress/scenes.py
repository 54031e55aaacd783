"""Hypothesis strategies for the property tests: small random volumes under random affine
transforms, seen by random orthographic and perspective cameras (the eye sometimes inside)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import strategies as st

import pcvr_native as pn
from pcvr_native import phantoms
from pcvr_native.cameras import look_at, perspective

from xray_helpers import CameraSpec, frame_ortho, frame_perspective, rotation


def _unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


directions = st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: np.linalg.norm(v) > 0.2).map(_unit)


@st.composite
def linear_parts(draw):
    """Rotation x anisotropic scale x shear x an optional mirror, condition number at most about 30."""
    axis = draw(directions)
    angle = draw(st.floats(0.0, math.pi))
    scales = np.diag([draw(st.floats(0.3, 3.0)) for _ in range(3)])
    shear = np.eye(3)
    shear[0, 1], shear[1, 2], shear[0, 2] = (draw(st.floats(-0.5, 0.5)) for _ in range(3))
    mirror = np.diag([-1.0 if draw(st.booleans()) else 1.0, 1.0, 1.0])
    return rotation(axis, angle) @ scales @ shear @ mirror


@st.composite
def volumes(draw, max_side=8, single_voxel=False):
    """(values, index_to_world): 2..max_side voxels a side, about half of them zero (inactive), the
    rest positive (or one voxel only); a centred transform with a random linear part, shifted."""
    shape = tuple(draw(st.integers(2, max_side)) for _ in range(3))
    rng = np.random.default_rng(draw(st.integers(0, 2 ** 32 - 1)))
    values = rng.uniform(0.1, 2.0, shape).astype(np.float32)
    values[rng.random(shape) < (1.0 if single_voxel else draw(st.floats(0.0, 0.8)))] = 0.0
    values.flat[0 if not single_voxel else int(rng.integers(values.size))] = 1.0  # never empty
    xf = phantoms.centred_transform(shape, 1.0, draw(linear_parts()))
    xf[:3, 3] += [draw(st.floats(-50.0, 50.0)) for _ in range(3)]
    return values, xf


@st.composite
def cameras_for(draw, volume, perspective=None, max_magnification=8.0):
    """A camera framing `volume`: orthographic or perspective (from 1.5 to 6 half-diagonals away),
    along a random direction, at a random magnification."""
    if perspective is None:
        perspective = draw(st.booleans())
    direction = draw(directions)
    up = draw(directions)
    if abs(np.dot(up, direction)) > 0.95:
        up = np.cross(direction, [1.0, 0.0, 0.0]) if abs(direction[0]) < 0.9 else np.cross(direction, [0.0, 1.0, 0.0])
    magnification = draw(st.floats(0.5, max_magnification))
    if perspective:
        return frame_perspective(volume, magnification, direction, up, distance=draw(st.floats(1.5, 6.0)))
    return frame_ortho(volume, magnification, direction, up, offset=(draw(st.floats(0, 1)), draw(st.floats(0, 1))))


@st.composite
def eyes_inside(draw, volume):
    """A perspective camera whose eye lies inside the volume's box, looking any way, with a near
    plane from a thousandth of a voxel to two voxels away."""
    values, xf = volume
    point = np.array([draw(st.floats(0.0, n - 1.0)) for n in values.shape])
    eye = xf[:3, :3] @ point + xf[:3, 3]
    voxel = float(np.abs(np.linalg.det(xf[:3, :3]))) ** (1.0 / 3.0)
    w2c = look_at(eye, eye + draw(directions), draw(directions))
    near = voxel * draw(st.floats(1e-3, 2.0))
    return CameraSpec(w2c, perspective(draw(st.floats(0.3, 2.5)), 1.0, near, 1e4 * voxel), 40, 40)


def grid_of(volume) -> pn.Grid:
    values, xf = volume
    return pn.Grid.from_dense(values, xf)
