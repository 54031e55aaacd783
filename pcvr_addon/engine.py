# SPDX-License-Identifier: GPL-3.0-or-later

"""Rendering: the one module that talks to pcvr_native (imported inside functions, so that the add-on
registers, and its settings can be edited, even where the native module cannot load)."""

import numpy as np

from . import cache, camera, volumes
from .properties import NATIVE_NAMES


def list_render_passes(scene, view_layer):
    """The passes of a render: (name, channel ids, channel type)."""
    yield ("Combined", "RGBA", 'COLOR')
    if view_layer.pcvr.use_pass_xray:
        yield ("XRay", "X", 'VALUE')


def register_passes(engine, scene, view_layer):
    for name, channel_ids, channel_type in list_render_passes(scene, view_layer):
        engine.register_pass(scene, view_layer, name, len(channel_ids), channel_ids, channel_type)


def read_grid(filepath, grid_name):
    import pcvr_native
    return pcvr_native.read_vdb(filepath, grid_name)


def load_grid(source):
    """The grid of a VolumeSource in world space. Raises OSError or ValueError naming the cause."""
    if source.error:
        raise OSError(source.error)
    if source.filepath:
        grid = cache.grids.get(source.filepath, source.grid_name, read_grid)
    else:
        with volumes.exported_grids(source.volume) as filepath:
            grid = read_grid(filepath, source.grid_name)
    return grid.with_index_to_world(source.object_to_world @ grid.index_to_world)


def native_camera(view):
    import pcvr_native
    return pcvr_native.Camera(view.world_to_camera, view.projection, view.width, view.height)


def render(engine, depsgraph):
    import pcvr_native

    view = camera.render_view(engine, depsgraph)
    if view is None:
        _fail(engine, "PCVR: the scene has no camera")
        return

    grids, density_scales = _load_volumes(engine, depsgraph, view)
    if engine.test_break():
        return

    settings = depsgraph.scene.pcvr
    stats = {}
    engine.update_stats("", "Rendering")
    if grids:
        try:
            integral = pcvr_native.render_xray(
                grids, native_camera(view),
                method=NATIVE_NAMES[settings.method],
                splat_kernel=NATIVE_NAMES[settings.splat_kernel],
                post_filter=NATIVE_NAMES[settings.post_filter],
                stride=settings.subgrid_stride,
                threads=depsgraph.scene.render.threads,
                density_scale=density_scales,
                progress=engine.update_progress,
                cancel=engine.test_break,
                stats=stats,
            )
        except pcvr_native.RenderCancelled:
            return
        except (MemoryError, ValueError, RuntimeError) as ex:  # RuntimeError: any other native error
            _fail(engine, f"PCVR: {ex}")
            return
    else:
        integral = np.zeros((view.height, view.width), dtype=np.float32)

    _write_result(engine, depsgraph, view, integral)
    engine.update_stats("", format_stats(stats))


def _load_volumes(engine, depsgraph, view):
    """The world-space grids in view and their density scales. A volume that cannot be read is
    reported and left out; the others still render."""
    grids, density_scales, errors = [], [], []
    for source in volumes.in_view(depsgraph, view):
        if engine.test_break():
            break
        engine.update_stats("", f"Reading {source.name}")
        try:
            grids.append(load_grid(source))
        except (OSError, ValueError, RuntimeError, MemoryError) as ex:
            message = f"Volume object '{source.name}': {ex}"
            engine.report({'ERROR'}, message)
            errors.append(message)
            continue
        density_scales.append(source.density_scale)
    if errors:
        engine.error_set("\n".join(errors))
    return grids, density_scales


def _fail(engine, message):
    engine.report({'ERROR'}, message)
    engine.error_set(message)


def pass_pixels(settings, film_transparent, integral):
    """The pixels of every pass from the line integral: {name: float32 (height, width, channels)}."""
    height, width = integral.shape
    combined = np.empty((height, width, 4), dtype=np.float32)
    combined[:, :, :3] = (-np.expm1(-settings.xray_gain * integral))[:, :, None]
    combined[:, :, 3] = (integral != 0) if film_transparent else 1.0
    return {"Combined": combined, "XRay": integral[:, :, None]}


def _write_result(engine, depsgraph, view, integral):
    view_layer = depsgraph.view_layer
    pixels = pass_pixels(depsgraph.scene.pcvr, depsgraph.scene.render.film_transparent, integral)
    # Result coordinates start at the render border, when there is one.
    result = engine.begin_result(0, 0, view.width, view.height, layer=view_layer.name)
    layer = result.layers[0]
    for name, _channel_ids, _channel_type in list_render_passes(depsgraph.scene, view_layer):
        # Blender stores rows bottom to top.
        rect = np.ascontiguousarray(pixels[name][::-1], dtype=np.float32)
        layer.passes[name].rect.foreach_set(rect.ravel())
    engine.end_result(result)


def format_stats(stats):
    """One line for the status bar from render_xray's statistics."""
    if not stats:
        return "No volume in view"
    low, high = stats["magnification"], stats["magnification_max"]
    magnification = f"{low:.2f}" if high - low < 0.005 else f"{low:.2f}-{high:.2f}"
    strides = ", ".join(str(stride) for stride in stats["strides"]) or "-"
    return (f"Voxels {stats['voxels']:,} | Magnification {magnification} px/voxel | Stride {strides} | "
            f"Time {stats['seconds']:.2f} s")


def object_grid(depsgraph, obj):
    """The world-space grid of the volume object `obj`, read through the cache."""
    obj_eval = obj.evaluated_get(depsgraph)
    return load_grid(volumes.source_of(obj_eval, obj_eval.matrix_world))


def sampling_estimate(depsgraph, settings):
    """What the scene camera makes of the volumes in view, from the grids already in the cache (the
    interface never reads files): ((min, max) pixels per voxel or None, subgrid strides, number of
    volumes not read yet). None without a camera."""
    import pcvr_native

    view = camera.scene_view(depsgraph)
    if view is None:
        return None
    native = native_camera(view)
    low, high, strides, unread = float("inf"), 0.0, set(), 0
    for source in volumes.in_view(depsgraph, view):
        grid = cache.grids.peek(source.filepath, source.grid_name) if source.filepath else None
        if grid is None:
            unread += 1
            continue
        grid = grid.with_index_to_world(source.object_to_world @ grid.index_to_world)
        grid_low, grid_high = pcvr_native.effective_magnification(grid, native)
        if grid_high == 0:
            continue  # none of its blocks is in view after all
        low, high = min(low, grid_low), max(high, grid_high)
        strides.add(settings.subgrid_stride or pcvr_native.automatic_stride(grid, native))
    return ((low, high) if high else None), sorted(strides), unread
