# SPDX-License-Identifier: GPL-3.0-or-later

"""F12: a render of the scene through its camera, stage by stage. The RenderEngine in __init__.py forwards here.

| mode     | pcvr_native call      | Combined pass                                                        |
|----------|-----------------------|----------------------------------------------------------------------|
| X-Ray    | render_xray           | 1 - exp(-gain * integral) in grey                                    |
| Shaded   | render_shaded         | premultiplied RGBA over the world colour (or transparent)            |
| MIP      | render_mip per volume | the largest density through the transfer function's colours, or grey |

A render goes through four stages, so that the viewport can run the last three on a worker thread (where
Blender's data must not be touched) and repeat only those that a change reaches. pcvr_native is imported inside
functions, so that the add-on registers, and its settings can be edited, even where the native module cannot load.

| stage   | function                        | runs on                | gives                                              |
|---------|---------------------------------|------------------------|----------------------------------------------------|
| read    | scene.scene_inputs.read         | Blender's main thread  | the scene as plain values                          |
| prepare | render.prepared_scene.prepare   | any thread             | world-space grids (through the cache), transfer functions, lights |
| render  | render.native_render.render_raw | any thread             | the native results: integral, RGBA and depth, maxima |
| finish  | render.passes.finish            | any thread             | the passes, then passes.write_result into Blender's render result |

render/statistics.py has what the user reads of a render: its progress, status line and the interface's rows.
"""

from .render import native_render, passes, prepared_scene, statistics
from .scene import camera, scene_inputs


def render(engine, depsgraph):
    """F12: the scene through its camera into the render result, errors and warnings reported on `engine`."""
    import pcvr_native

    view = camera.render_view(engine, depsgraph)
    if view is None:
        _fail(engine, "PCVR: the scene has no camera")
        return

    inputs, display = scene_inputs.read(depsgraph, prepared_scene.export_grid, view)
    try:
        prepared = prepared_scene.prepare(inputs, engine.test_break, lambda name: engine.update_stats("", f"Reading {name}"))
    except ValueError as ex:
        _fail(engine, f"PCVR: {ex}")
        return
    _report_errors(engine, prepared.errors)
    for message in prepared.warnings:
        engine.report({'WARNING'}, message)
    if engine.test_break():
        return

    engine.update_stats("", "Rendering")
    stats = {}
    voxels = sum(volume.grid.active_voxel_count for volume in prepared.volumes) if inputs.mode == 'XRAY' else None
    try:
        control = native_render.Control(statistics.ProgressReport(engine, voxels), engine.test_break)
        raw = native_render.render_raw(prepared, view, control, stats)
    except pcvr_native.RenderCancelled:
        return
    except (MemoryError, ValueError, RuntimeError) as ex:  # RuntimeError: any other native error
        _fail(engine, f"PCVR: {ex}")
        return

    passes.write_result(engine, depsgraph, view, passes.finish(display, raw))
    if prepared.streamed:
        stats["streamed"] = prepared.streamed
    stream_level = max((volume.level for volume in prepared.volumes), default=0)
    if stream_level:
        stats["level"] = stats.get("level", 0) + stream_level  # of the volume itself, not of its level
    statistics.last_render[depsgraph.scene.session_uid] = (inputs.mode, stats)
    engine.update_stats("", statistics.status_line(inputs.mode, stats))


def _report_errors(engine, errors):
    for message in errors:
        engine.report({'ERROR'}, message)
    if errors:
        engine.error_set("\n".join(errors))


def _fail(engine, message):
    engine.report({'ERROR'}, message)
    engine.error_set(message)
