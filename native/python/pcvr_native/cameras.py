"""Camera matrices in the conventions of pcvr_native.Camera (and of Blender): OpenGL clip matrices,
column vectors, the camera looking down its own -Z axis.

These are what `Object.calc_matrix_camera` and `matrix_world.inverted()` give inside Blender; outside
it, scripts and tests build the same matrices with these helpers.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

__all__ = ["ortho", "frustum", "perspective", "look_at", "cone_beam"]


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


def _source_view(sad, isocentre=(0.0, 0.0, 0.0), gantry=0.0, tilt=0.0) -> np.ndarray:
    """world_to_camera of a C-arm's X-ray source (see cone_beam): at isocentre + sad * d, looking at the
    isocentre, image up +z tilted with the source, image right the camera's right seen from the source."""
    sad = _positive("sad", sad)
    isocentre = _finite_vector("isocentre", isocentre, 3)
    gantry, tilt = math.radians(_finite("gantry", gantry)), math.radians(_finite("tilt", tilt))
    # Gantry 0: the source anterior (-y, LPS); 90: at the patient's left (+x). Tilt turns it towards +z.
    level = np.array([math.sin(gantry), -math.cos(gantry), 0.0])
    towards_source = math.cos(tilt) * level + math.sin(tilt) * np.array([0.0, 0.0, 1.0])
    up = -math.sin(tilt) * level + math.cos(tilt) * np.array([0.0, 0.0, 1.0])
    right = np.cross(-towards_source, up)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = right, up, towards_source
    m[:3, 3] = -m[:3, :3] @ (isocentre + sad * towards_source)
    return m


def cone_beam(sad, sid, detector, pixel_spacing, isocentre=(0.0, 0.0, 0.0), gantry=0.0, tilt=0.0,
              detector_offset=(0.0, 0.0)):
    """The pcvr_native.Camera of a C-arm (cone-beam) radiograph, in world millimetres (LPS for scans).

    | parameter | meaning |
    |---|---|
    | sad | source to isocentre distance |
    | sid | source to detector distance, more than `sad` |
    | detector | (cols, rows): the image's pixels |
    | pixel_spacing | (du, dv): a detector pixel's width and height |
    | isocentre | (x, y, z): the point the central ray passes through |
    | gantry | degrees; the source sits at isocentre + sad * Rz(gantry) (0, -1, 0): 0 anterior, 90 at +x (left) |
    | tilt | degrees; turns the source towards +z (cranial in LPS) out of the gantry's plane |
    | detector_offset | (u, v): the detector's centre moved right and up in the image, millimetres |

    The detector is perpendicular to the central ray at `sid` from the source; row 0 is its top (image up is +z,
    tilted with the source) and image right is the camera's right seen from the source. Pixel (c, r) has its
    centre at u = (c + 0.5 - cols / 2) du + offset_u, v = (rows / 2 - r - 0.5) dv + offset_v on the detector,
    as every Camera places pixels. Voxels nearer the source than a hundredth of `sad` are not imaged.
    """
    from . import Camera

    sid = _positive("sid", sid)
    view = _source_view(sad, isocentre, gantry, tilt)
    if not sid > sad:
        raise ValueError(f"cone_beam: the source to detector distance (sid {sid}) must exceed the source to "
                         f"isocentre distance (sad {sad})")
    cols, rows = _detector_size(detector)
    du, dv = (_positive(f"pixel_spacing[{axis}]", value)
              for axis, value in enumerate(_finite_vector("pixel_spacing", pixel_spacing, 2)))
    offset_u, offset_v = _finite_vector("detector_offset", detector_offset, 2)
    # The detector's window, scaled from `sid` onto the near plane.
    near, far = 0.01 * sad, 100.0 * sid
    scale = near / sid
    half_u, half_v = cols * du / 2.0, rows * dv / 2.0
    projection = frustum((offset_u - half_u) * scale, (offset_u + half_u) * scale,
                         (offset_v - half_v) * scale, (offset_v + half_v) * scale, near, far)
    return Camera(view, projection, cols, rows)


def _finite(name, value):
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise TypeError(f"cone_beam: {name} must be a number, not {value!r}") from None
    if not math.isfinite(value):
        raise ValueError(f"cone_beam: {name} must be finite, not {value}")
    return value


def _positive(name, value):
    value = _finite(name, value)
    if not value > 0:
        raise ValueError(f"cone_beam: {name} must be positive, not {value}")
    return value


def _finite_vector(name, values, count):
    try:
        values = [float(v) for v in values]
    except (TypeError, ValueError):
        raise TypeError(f"cone_beam: {name} must be {count} numbers, not {values!r}") from None
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise ValueError(f"cone_beam: {name} must be {count} finite numbers, not {values}")
    return np.array(values)


def _detector_size(detector):
    try:
        cols, rows = detector
    except (TypeError, ValueError):
        raise TypeError(f"cone_beam: detector must be (cols, rows), not {detector!r}") from None
    for name, value in (("cols", cols), ("rows", rows)):
        whole = isinstance(value, numbers.Integral) and not isinstance(value, bool)
        if not whole or not 1 <= value <= 1 << 16:
            raise ValueError(f"cone_beam: detector {name} must be a whole number of pixels from 1 to 65536, "
                             f"not {value!r}")
    return int(cols), int(rows)
