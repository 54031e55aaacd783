"""Camera matrices in the conventions of pcvr_native.Camera (and of Blender): OpenGL clip matrices,
column vectors, the camera looking down its own -Z axis.

These are what `Object.calc_matrix_camera` and `matrix_world.inverted()` give inside Blender; outside
it, scripts and tests build the same matrices with these helpers.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["ortho", "frustum", "perspective", "look_at"]


def ortho(left, right, bottom, top, near, far) -> np.ndarray:
    m = np.zeros((4, 4))
    m[0, 0] = 2.0 / (right - left)
    m[1, 1] = 2.0 / (top - bottom)
    m[2, 2] = -2.0 / (far - near)
    m[0, 3] = -(right + left) / (right - left)
    m[1, 3] = -(top + bottom) / (top - bottom)
    m[2, 3] = -(far + near) / (far - near)
    m[3, 3] = 1.0
    return m


def frustum(left, right, bottom, top, near, far) -> np.ndarray:
    """glFrustum: the window [left, right] x [bottom, top] lies on the near plane."""
    m = np.zeros((4, 4))
    m[0, 0] = 2.0 * near / (right - left)
    m[1, 1] = 2.0 * near / (top - bottom)
    m[0, 2] = (right + left) / (right - left)
    m[1, 2] = (top + bottom) / (top - bottom)
    m[2, 2] = -(far + near) / (far - near)
    m[2, 3] = -2.0 * far * near / (far - near)
    m[3, 2] = -1.0
    return m


def perspective(fov_y, aspect, near, far) -> np.ndarray:
    """gluPerspective; fov_y in radians."""
    top = near * math.tan(fov_y / 2.0)
    return frustum(-top * aspect, top * aspect, -top, top, near, far)


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """world_to_camera for a camera at `eye` looking at `target` (down its own -Z)."""
    eye = np.asarray(eye, dtype=np.float64)
    forward = np.asarray(target, dtype=np.float64) - eye
    forward /= np.linalg.norm(forward)
    up = np.asarray(up, dtype=np.float64)
    if abs(np.dot(forward, up / np.linalg.norm(up))) > 0.999:
        up = np.array([0.0, 1.0, 0.0]) if abs(forward[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = np.cross(forward, up)
    x /= np.linalg.norm(x)
    y = np.cross(x, forward)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = x, y, -forward
    m[:3, 3] = -m[:3, :3] @ eye
    return m
