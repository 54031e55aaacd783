# SPDX-License-Identifier: GPL-3.0-or-later

"""The render camera as pcvr_native sees it: a view matrix, an OpenGL projection and a pixel window; for
renders from the scene camera, and for the 3D viewport from its region (orthographic, perspective, or through
the camera with its zoom, offset and render border)."""

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class CameraView:
    world_to_camera: np.ndarray  # (4, 4), camera looks down -Z
    projection: np.ndarray       # (4, 4), camera space to the clip space of this window
    width: int                   # image size in pixels
    height: int

    def __eq__(self, other):
        return (isinstance(other, CameraView) and (self.width, self.height) == (other.width, other.height)
                and np.array_equal(self.world_to_camera, other.world_to_camera)
                and np.array_equal(self.projection, other.projection))

    __hash__ = None

    def scaled(self, scale):
        """The same view at 1/scale of the pixels in each direction (at least one)."""
        return CameraView(self.world_to_camera, self.projection,
                          max(1, math.ceil(self.width / scale)), max(1, math.ceil(self.height / scale)))

    def sees_box(self, corners):
        """False when the world-space points `corners` (N, 3), e.g. a bounding box, all lie on the outer
        side of one clip plane, so nothing inside their convex hull can reach the image."""
        points = np.c_[np.asarray(corners, dtype=np.float64), np.ones(len(corners))]
        x, y, z, w = self.projection @ self.world_to_camera @ points.T
        # The planes are linear in homogeneous coordinates, so this also holds for points behind
        # a perspective camera (w < 0).
        outside = ((x > w).all() or (x < -w).all() or
                   (y > w).all() or (y < -w).all() or
                   (z > w).all() or (z < -w).all())
        return not outside


# Blender's numpad views (and an isometric one from the front right, above): the direction the camera looks
# along and the world direction that shows up in the image.
AXIS_VIEWS = {
    'TOP': ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0)),      # numpad 7
    'BOTTOM': ((0.0, 0.0, 1.0), (0.0, -1.0, 0.0)),   # ctrl numpad 7
    'FRONT': ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),     # numpad 1
    'BACK': ((0.0, -1.0, 0.0), (0.0, 0.0, 1.0)),     # ctrl numpad 1
    'RIGHT': ((-1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),    # numpad 3
    'LEFT': ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),      # ctrl numpad 3
    'ISO': ((-1.0, 1.0, -1.0), (0.0, 0.0, 1.0)),
}


def look_rotation(direction, up=None):
    """(3, 3) rotation of a camera looking along `direction` (its local -Z) with `up` as near its image's up
    (local +Y) as can be: world Z, or world Y when looking along Z. ValueError for a zero direction."""
    forward = np.asarray(direction, dtype=np.float64)
    length = np.linalg.norm(forward)
    if not (length > 0 and np.isfinite(length)):
        raise ValueError(f"a view direction needs a length, not {tuple(direction)}")
    back = -forward / length
    if up is None:
        up = (0.0, 1.0, 0.0) if abs(back[2]) > 0.999 else (0.0, 0.0, 1.0)
    right = np.cross(up, back)
    right /= np.linalg.norm(right)
    return np.column_stack([right, np.cross(back, right), back])


def border_window(render, width, height):
    """The pixel rectangle (x, y, width, height) Blender renders for the render border, from the bottom
    left of the frame, or None when the whole frame is rendered."""
    if not render.use_border:
        return None
    # Blender computes the border in single precision and truncates; do the same so the window
    # matches the size of the result Blender hands out.
    f = np.float32
    xmin, xmax = int(f(render.border_min_x) * f(width)), int(f(render.border_max_x) * f(width))
    ymin, ymax = int(f(render.border_min_y) * f(height)), int(f(render.border_max_y) * f(height))
    if (xmin, ymin, xmax, ymax) == (0, 0, width, height):
        return None
    return xmin, ymin, xmax - xmin, ymax - ymin


def window_projection(projection, width, height, window):
    """Narrow a full-frame projection to the pixel window (x, y, w, h): the window maps to NDC [-1, 1]."""
    x, y, w, h = window
    sx, sy = w / width, h / height
    # Centre of the window in full-frame NDC.
    cx, cy = (2 * x + w) / width - 1, (2 * y + h) / height - 1
    to_window = np.array([
        [1 / sx, 0, 0, -cx / sx],
        [0, 1 / sy, 0, -cy / sy],
        [0, 0, 1, 0],
        [0, 0, 0, 1],
    ])
    return to_window @ projection


def camera_view(depsgraph, camera_eval, model_matrix, width, height):
    """The full frame of `width` x `height` pixels seen by the evaluated camera placed at `model_matrix`."""
    render = depsgraph.scene.render
    projection = camera_eval.calc_matrix_camera(
        depsgraph, x=width, y=height, scale_x=render.pixel_aspect_x, scale_y=render.pixel_aspect_y)
    return CameraView(
        world_to_camera=np.linalg.inv(np.array(model_matrix, dtype=np.float64)),
        projection=np.array(projection, dtype=np.float64),
        width=width,
        height=height,
    )


def render_view(engine, depsgraph):
    """What `engine` renders now: its camera and resolution, narrowed to the render border if one is set
    (Blender's render result then covers only the border). None when the scene has no camera."""
    scene = depsgraph.scene
    camera_object = engine.camera_override or scene.camera
    if camera_object is None:
        return None
    camera_eval = camera_object.evaluated_get(depsgraph)
    width, height = engine.resolution_x, engine.resolution_y
    # The matrix of the view being rendered (stereo aware), without scale.
    model_matrix = engine.camera_model_matrix(camera_eval, use_spherical_stereo=False)
    view = camera_view(depsgraph, camera_eval, model_matrix, width, height)

    window = border_window(scene.render, width, height)
    if window is None:
        return view
    return CameraView(
        world_to_camera=view.world_to_camera,
        projection=window_projection(view.projection, width, height, window),
        width=window[2],
        height=window[3],
    )


def scene_view(depsgraph):
    """The full frame of the scene camera at the output resolution, for estimates outside a render."""
    scene = depsgraph.scene
    if scene.camera is None:
        return None
    render = scene.render
    width = render.resolution_x * render.resolution_percentage // 100
    height = render.resolution_y * render.resolution_percentage // 100
    camera_eval = scene.camera.evaluated_get(depsgraph)
    return camera_view(depsgraph, camera_eval, camera_eval.matrix_world.normalized(), width, height)


# -------------------------------------------------------------------------------------------------
# The 3D viewport

@dataclass(frozen=True)
class RegionView:
    """What a 3D viewport region renders, and where the image goes."""
    view: CameraView   # at full resolution: the window's pixels divided by the preview pixel size
    rect: tuple        # (x, y, width, height) of the window in region pixels from the bottom left


def window_view(view_matrix, window_matrix, region_size, window=None, pixel_size=1):
    """RegionView of a region `region_size` (width, height) pixels large whose view and window matrices are
    Blender's RegionView3D.view_matrix and .window_matrix, narrowed to `window` (x, y, width, height) in region
    pixels when given, rendered at one image pixel per `pixel_size` region pixels. None for an empty window."""
    width, height = region_size
    x, y, w, h = window or (0, 0, width, height)
    if w <= 0 or h <= 0:
        return None
    projection = np.array(window_matrix, dtype=np.float64)
    if (x, y, w, h) != (0, 0, width, height):
        projection = window_projection(projection, width, height, (x, y, w, h))
    view = CameraView(np.array(view_matrix, dtype=np.float64), projection,
                      max(1, math.ceil(w / pixel_size)), max(1, math.ceil(h / pixel_size)))
    return RegionView(view, (x, y, w, h))


def region_pixels(points, perspective_matrix, region_size):
    """World points (N, 3) as region pixel coordinates (N, 2) from the bottom left."""
    points = np.c_[np.asarray(points, dtype=np.float64), np.ones(len(points))]
    clip = points @ np.asarray(perspective_matrix, dtype=np.float64).T
    ndc = clip[:, :2] / clip[:, 3:]
    return (ndc + 1.0) / 2.0 * np.asarray(region_size, dtype=np.float64)


def clipped_window(lo, hi, region_size):
    """The whole pixels (x, y, width, height) from `lo` to `hi` (region pixels) inside the region, as Blender
    rounds a render border."""
    (x0, y0), (x1, y1) = np.floor(np.maximum(lo, 0)), np.floor(np.minimum(hi, region_size))
    return int(x0), int(y0), max(0, int(x1 - x0)), max(0, int(y1 - y0))

