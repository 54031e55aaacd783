"""Cameras of the benchmark, defined as Blender cameras so that every renderer sees the same one.

A view is a dict of Blender camera settings (object matrix, ORTHO with ``ortho_scale`` or PERSP with
``lens`` and ``sensor_width``, clip range, resolution; sensor fit AUTO, no shift, square pixels).
:func:`matrices` turns it into the (world_to_camera, projection) pair that
``Object.calc_matrix_camera`` returns for it; the Blender peers set the camera up from the same dict
and record how far Blender's own matrices are from these (``camera_error`` in the results), and VTK
gets the same matrices explicitly. So PCVR, Cycles, EEVEE and VTK render through one camera.

| view        | what                                                                                    |
|-------------|-----------------------------------------------------------------------------------------|
| ``m1``..``m8`` | orthographic, oblique (no volume axis parallel to the view or to an image axis), framing |
|             | the whole volume plus the kernel radius, m pixels per voxel                              |
| ``persp``   | pinhole camera on the same axis, 1.5 volume diagonals away, 4 pixels per voxel at the    |
|             | volume's centre (about 3 on the far side, 6 on the near side)                            |
"""

from __future__ import annotations

import math

import numpy as np
from pcvr_native.cameras import frustum, look_at, ortho

VIEW_DIRECTION = (-0.62, 0.47, -0.63)
VIEW_UP = (0.6, -0.3, 1.0)
KERNEL_RADIUS = 2.0
MARGIN_PIXELS = 2
PERSPECTIVE_MAGNIFICATION = 4.0
PERSPECTIVE_DISTANCE = 1.5
SENSOR_WIDTH = 36.0  # mm, Blender's default


def _framing(shape, index_to_world, direction=VIEW_DIRECTION):
    """World corners of the volume grown by the kernel radius, their centre, the diagonal, the view axis."""
    xf = np.asarray(index_to_world, dtype=np.float64)
    lo = np.zeros(3) - KERNEL_RADIUS
    hi = np.asarray(shape, dtype=np.float64) - 1 + KERNEL_RADIUS
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    world = corners @ xf[:3, :3].T + xf[:3, 3]
    d = np.asarray(direction, dtype=np.float64)
    return world, world.mean(axis=0), float(np.linalg.norm(world.max(axis=0) - world.min(axis=0))), d / np.linalg.norm(d)


def _depth_range(world, w2c):
    """Nearest and farthest distance in front of the camera of the framed corners (EEVEE's volume range)."""
    depth = -(world @ w2c[:3, :3].T + w2c[:3, 3])[:, 2]
    return [float(depth.min()), float(depth.max())]


def oblique(shape, index_to_world, magnification: float, direction=VIEW_DIRECTION, up=VIEW_UP) -> dict:
    """Orthographic view along `direction`, `magnification` pixels per voxel in the least
    magnified image direction, framing the whole volume."""
    xf = np.asarray(index_to_world, dtype=np.float64)
    world, centre, diag, d = _framing(shape, xf, direction)
    w2c = look_at(centre - d * diag, centre, up)
    pixel = float(np.linalg.svd(w2c[:2, :3] @ xf[:3, :3], compute_uv=False).min()) / magnification
    cam_xy = (world @ w2c[:3, :3].T + w2c[:3, 3])[:, :2]
    half = np.abs(cam_xy).max(axis=0)
    width = int(math.ceil(2.0 * half[0] / pixel)) + 2 * MARGIN_PIXELS
    height = int(math.ceil(2.0 * half[1] / pixel)) + 2 * MARGIN_PIXELS
    return {"type": "ORTHO", "matrix_world": np.linalg.inv(w2c).tolist(), "ortho_scale": pixel * max(width, height),
            "clip_start": 0.25 * diag, "clip_end": 1.75 * diag, "width": width, "height": height,
            "magnification": float(magnification), "depth_range": _depth_range(world, w2c)}


def perspective(shape, index_to_world, magnification: float = PERSPECTIVE_MAGNIFICATION, square: int | None = None,
                fov_degrees: float | None = None) -> dict:
    """Pinhole view along VIEW_DIRECTION, PERSPECTIVE_DISTANCE diagonals from the centre, with
    `magnification` pixels per voxel there, framing the whole volume; or, with `square`, a square image
    of that many pixels a side that the volume fills (the magnification then follows from it), and with
    `fov_degrees` as well, from the distance at which that field of view (across the image) fits it."""
    xf = np.asarray(index_to_world, dtype=np.float64)
    world, centre, diag, d = _framing(shape, xf)

    def fitted(distance):
        w2c = look_at(centre - d * distance, centre, VIEW_UP)
        cam = world @ w2c[:3, :3].T + w2c[:3, 3]
        return w2c, (np.abs(cam[:, :2]) / -cam[:, 2:3]).max(axis=0)  # half the image per unit of focal length

    distance = PERSPECTIVE_DISTANCE * diag
    if fov_degrees is not None and square is not None:
        # The volume's half-extent over the focal length falls as the camera backs off: bisect for the
        # distance where it fills the image inside the margins at this field of view.
        goal = math.tan(math.radians(fov_degrees) / 2.0) * (square - 2 * MARGIN_PIXELS) / square
        near, far = 0.5 * diag, 100.0 * diag
        for _ in range(60):
            distance = 0.5 * (near + far)
            near, far = (distance, far) if fitted(distance)[1].max() > goal else (near, distance)
    w2c, extent = fitted(distance)
    voxel = float(np.linalg.svd(w2c[:2, :3] @ xf[:3, :3], compute_uv=False).min())
    if square is not None:
        focal = (square - 2 * MARGIN_PIXELS) / (2.0 * float(extent.max()))
        magnification = focal * voxel / distance
        width = height = int(square)
    else:
        focal = magnification * distance / voxel  # pixels per unit of x / depth
        width, height = (int(math.ceil(2.0 * h * focal)) + 2 * MARGIN_PIXELS for h in extent)
    return {"type": "PERSP", "matrix_world": np.linalg.inv(w2c).tolist(),
            "lens": focal * SENSOR_WIDTH / max(width, height), "sensor_width": SENSOR_WIDTH,
            "clip_start": distance - 0.75 * diag, "clip_end": distance + 0.75 * diag,
            "width": width, "height": height, "magnification": float(magnification),
            "depth_range": _depth_range(world, w2c)}


def matrices(view: dict):
    """(world_to_camera, projection) as Blender computes them for `view` (sensor fit AUTO: the
    ortho scale or the sensor spans the larger image dimension)."""
    w2c = np.linalg.inv(np.asarray(view["matrix_world"], dtype=np.float64))
    w, h = view["width"], view["height"]
    near, far = view["clip_start"], view["clip_end"]
    if view["type"] == "ORTHO":
        pixel = view["ortho_scale"] / max(w, h)
        return w2c, ortho(-0.5 * w * pixel, 0.5 * w * pixel, -0.5 * h * pixel, 0.5 * h * pixel, near, far)
    pixel = view["sensor_width"] * near / view["lens"] / max(w, h)  # size of a pixel on the near plane
    return w2c, frustum(-0.5 * w * pixel, 0.5 * w * pixel, -0.5 * h * pixel, 0.5 * h * pixel, near, far)


def camera(view: dict):
    import pcvr_native as pn
    w2c, proj = matrices(view)
    return pn.Camera(w2c, proj, view["width"], view["height"])


def views_for(phantom, magnifications, with_perspective: bool = True) -> dict:
    shape = phantom.values.shape
    out = {f"m{m}": oblique(shape, phantom.index_to_world, m) for m in magnifications}
    if with_perspective:
        out["persp"] = perspective(shape, phantom.index_to_world)
    return out
