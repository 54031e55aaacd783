# SPDX-License-Identifier: GPL-3.0-or-later

"""Blender's side of the rendered viewport (Viewport Shading: Rendered): one ViewportSession per RenderEngine
that Blender makes for a 3D viewport region.

- view_update (a change in the depsgraph) reads the scene into plain values (scene_inputs) and hands them to
  the session's viewport.ProgressiveRenderer, which decides whether anything must be rendered again.
- view_draw reads the region's view (view and window matrices, size, render border) and hands it over too,
  then draws the newest image (viewport_draw) and shows the state in the viewport's text.

The renderer's worker thread touches no Blender data: when an image is ready it only tags the engine for a
redraw, through a weak reference, so that a session never keeps its engine alive.
"""

import weakref

import numpy as np

from ..scene import camera, scene_inputs
from . import native_render, passes, prepared_scene, viewport


def _tag_redraw(engine_reference):
    render_engine = engine_reference()
    if render_engine is None:
        return
    try:
        render_engine.tag_redraw()  # sets a flag that Blender's main loop polls: safe from any thread
    except ReferenceError:
        pass  # Blender freed the engine; its __del__ stops this session


def _resolution(step):
    return "full resolution" if step.scale == 1 else f"1/{step.scale} resolution"


class ViewportSession:
    def __init__(self, render_engine):
        reference = weakref.ref(render_engine)
        self.renderer = viewport.ProgressiveRenderer(
            prepared_scene.Preparer(), native_render.render_viewport_step, passes.viewport_pixels,
            on_image=lambda: _tag_redraw(reference), cost_key=lambda inputs: inputs.mode)
        self._exports = {}   # object name -> grid of a procedural volume, kept until its geometry changes
        self._texture = None

    def update(self, context, depsgraph):
        """view_update: read the scene."""
        for update in depsgraph.updates:
            if update.is_updated_geometry:
                self._exports.pop(update.id.name, None)
        space = context.space_data
        # Only local views and local collections make the viewport show less than its depsgraph holds.
        local = space if space.local_view or space.use_local_collections else None
        inputs, display = scene_inputs.read(depsgraph, self._export, in_viewport=True, space=local)
        self.renderer.update_scene(inputs, display)

    def _export(self, source):
        if source.name not in self._exports:
            self._exports[source.name] = prepared_scene.export_grid(source)
        return self._exports[source.name]

    def draw(self, render_engine, context, depsgraph):
        """view_draw: hand over the region's view, draw the newest image."""
        scene = depsgraph.scene
        region_view = viewport_region_view(context, depsgraph, render_engine.get_preview_pixel_size(scene))
        self.renderer.update_view(None if region_view is None else region_view.view)
        render_engine.update_stats("", self.status())
        image = self.renderer.latest()
        if image is None or region_view is None:
            return
        from . import viewport_draw
        if self._texture is None:
            self._texture = viewport_draw.ImageTexture()
        viewport_draw.draw(render_engine, scene, self._texture.of(image), region_view.rect)

    def status(self):
        """One line for the viewport's text: what the image is, or what went wrong."""
        error = self.renderer.error
        if error:
            return f"PCVR: {error}"
        prepared = self.renderer.prepared()
        problems = prepared.errors if prepared is not None else []
        running, image = self.renderer.running, self.renderer.latest()
        if running is not None:
            state = f"Rendering {_resolution(self.renderer.schedule.steps[running.index])}"
        elif image is not None:
            state = "Done" if image.step.scale == 1 else _resolution(image.step)
        else:
            state = "Waiting"
        if image is not None:
            height, width = image.pixels.shape[:2]
            state += f" | {width} x {height} in {image.seconds * 1000:.0f} ms"
        return " | ".join([state] + problems)

    def free(self):
        self.renderer.stop()


def viewport_region_view(context, depsgraph, pixel_size=1):
    """camera.RegionView of the 3D viewport region being drawn, or None when its render border is empty."""
    region, region_3d = context.region, context.region_data
    size = (region.width, region.height)
    window = region_window(context, depsgraph, size)
    return camera.window_view(region_3d.view_matrix, region_3d.window_matrix, size, window, pixel_size)


def region_window(context, depsgraph, size):
    """The part of the region to render, (x, y, width, height) in region pixels, or None for all of it: looking
    through the camera, the scene's render border within the camera's frame; otherwise the viewport's own render
    border."""
    scene, region_3d, space = depsgraph.scene, context.region_data, context.space_data
    if region_3d.view_perspective == 'CAMERA':
        render = scene.render
        if not render.use_border:
            return None
        lo, hi = camera_frame(space, depsgraph, region_3d.perspective_matrix, size)
        border_lo, border_hi = (render.border_min_x, render.border_min_y), (render.border_max_x, render.border_max_y)
        return camera.clipped_window(lo + (hi - lo) * border_lo, lo + (hi - lo) * border_hi, size)
    if not space.use_render_border:
        return None
    lo = (space.render_border_min_x * size[0], space.render_border_min_y * size[1])
    hi = (space.render_border_max_x * size[0], space.render_border_max_y * size[1])
    return camera.clipped_window(lo, hi, size)


def camera_frame(space, depsgraph, perspective_matrix, size):
    """The lower left and upper right corners of the camera's frame in region pixels (camera view)."""
    scene = depsgraph.scene
    camera_object = space.camera if getattr(space, "use_local_camera", False) and space.camera else scene.camera
    camera_eval = camera_object.evaluated_get(depsgraph)
    matrix = np.array(camera_eval.matrix_world.normalized(), dtype=np.float64)
    corners = np.array([tuple(corner) for corner in camera_eval.data.view_frame(scene=scene)], dtype=np.float64)
    world = corners @ matrix[:3, :3].T + matrix[:3, 3]
    pixels = camera.region_pixels(world, perspective_matrix, size)
    return pixels.min(axis=0), pixels.max(axis=0)


# -------------------------------------------------------------------------------------------------
# What the engine's callbacks forward to

def session_of(render_engine):
    if render_engine.viewport_session is None:
        render_engine.viewport_session = ViewportSession(render_engine)
    return render_engine.viewport_session


def view_update(render_engine, context, depsgraph):
    session_of(render_engine).update(context, depsgraph)


def view_draw(render_engine, context, depsgraph):
    session_of(render_engine).draw(render_engine, context, depsgraph)


def free(render_engine):
    session = getattr(render_engine, "viewport_session", None)
    if session is not None:
        session.free()
        render_engine.viewport_session = None
