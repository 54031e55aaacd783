"""Stand-ins for what Blender hands to view_update and view_draw: a render engine and a 3D viewport region.

Blender makes a viewport's RenderEngine only for a 3D view in a window, and `bpy` in background mode has no
window. The stand-ins carry exactly what viewport_session reads (the region's size, view and window matrices,
the viewport's render border) and record what it does with the engine; the scene, the depsgraph and the
renders behind them are real. The drawing itself (viewport_draw, which needs a GPU) is replaced by a recorder
through `record_draws`.
"""

import threading
from types import SimpleNamespace

import bpy
import numpy as np
from mathutils import Matrix

from pcvr_addon.render import viewport_draw, viewport_session

# Long enough for any render of these small scenes on a busy machine; only reached when something hangs.
IDLE_TIMEOUT = 60.0


class StandInEngine:
    """What viewport_session uses of a RenderEngine."""

    def __init__(self, pixel_size=1):
        self.viewport_session = None
        self.pixel_size = pixel_size
        self.status = ""
        self._redraws = 0
        self._lock = threading.Lock()

    def tag_redraw(self):  # called from the worker thread
        with self._lock:
            self._redraws += 1

    @property
    def redraws(self):
        with self._lock:
            return self._redraws

    def update_stats(self, stats, info):
        self.status = info

    def get_preview_pixel_size(self, scene):
        return self.pixel_size

    @property
    def renderer(self):
        return self.viewport_session.renderer

    def update(self, context):
        """view_update as Blender calls it: from inside the depsgraph's update, whose `updates` then list what
        changed; directly when nothing was tagged (as for the first draw)."""
        called = []

        def handler(_scene, depsgraph):
            called.append(True)
            viewport_session.view_update(self, context, depsgraph)

        bpy.app.handlers.depsgraph_update_post.append(handler)
        try:
            depsgraph = bpy.context.evaluated_depsgraph_get()
        finally:
            bpy.app.handlers.depsgraph_update_post.remove(handler)
        if not called:
            viewport_session.view_update(self, context, depsgraph)

    def draw(self, context):
        viewport_session.view_draw(self, context, bpy.context.evaluated_depsgraph_get())

    def settle(self, context):
        """view_update and view_draw, as Blender calls them after a change; wait for the last image, and draw
        it, as Blender does after tag_redraw."""
        self.update(context)
        self.draw(context)
        assert self.renderer.wait_until_idle(IDLE_TIMEOUT), "the viewport never finished rendering"
        self.draw(context)

    def free(self):
        viewport_session.free(self)


def region_context(view_matrix, window_matrix, width, height, perspective='PERSP', render_border=None):
    """A 3D viewport region `width` x `height` pixels with Blender's view and window matrices; `render_border`:
    the viewport's own render border (min_x, min_y, max_x, max_y) as fractions of the region."""
    view_matrix, window_matrix = Matrix(view_matrix), Matrix(window_matrix)
    border = render_border or (0.0, 0.0, 1.0, 1.0)
    space = SimpleNamespace(local_view=None, use_local_collections=False, camera=None, use_local_camera=False,
                            use_render_border=render_border is not None,
                            render_border_min_x=border[0], render_border_min_y=border[1],
                            render_border_max_x=border[2], render_border_max_y=border[3])
    region_3d = SimpleNamespace(view_matrix=view_matrix, window_matrix=window_matrix,
                                perspective_matrix=window_matrix @ view_matrix, view_perspective=perspective)
    return SimpleNamespace(region=SimpleNamespace(width=width, height=height), region_data=region_3d,
                           space_data=space)


def camera_context(camera, width, height, zoom=1.0):
    """Looking through `camera` in a region `width` x `height`: the camera's frame fills the region, or with
    `zoom` < 1 that share of it, centred (as Blender's camera view zoomed out)."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    camera_eval = camera.evaluated_get(depsgraph)
    frame_width, frame_height = round(width * zoom), round(height * zoom)
    projection = camera_eval.calc_matrix_camera(depsgraph, x=frame_width, y=frame_height)
    window = Matrix.Diagonal((zoom, zoom, 1.0, 1.0)) @ projection
    return region_context(camera_eval.matrix_world.normalized().inverted(), window, width, height, 'CAMERA')


def moved(context, offset):
    """The same region with the view moved sideways by `offset` world units."""
    view_matrix = Matrix.Translation((offset, 0.0, 0.0)) @ context.region_data.view_matrix
    return region_context(view_matrix, context.region_data.window_matrix, context.region.width,
                          context.region.height, context.region_data.view_perspective)


def ortho_projection(half_width, half_height, near=0.1, far=100.0):
    projection = np.diag([1 / half_width, 1 / half_height, -2 / (far - near), 1.0])
    projection[2, 3] = -(far + near) / (far - near)
    return projection


def watch_renders(renderer):
    """Record every render the renderer starts: returns the list of (Job, view) it appends to. The render
    itself runs as before."""
    started, render = [], renderer._render

    def watched(prepared, view, step, cancel):
        started.append((renderer.running, view))
        return render(prepared, view, step, cancel)

    renderer._render = watched
    return started


def record_draws(monkeypatch):
    """Replace the GPU drawing by a recorder: returns the list of (image, rect) drawn."""
    draws = []
    monkeypatch.setattr(viewport_draw, "upload", lambda pixels: pixels)
    monkeypatch.setattr(viewport_draw, "draw", lambda engine, scene, texture, rect: draws.append((texture, rect)))
    return draws
