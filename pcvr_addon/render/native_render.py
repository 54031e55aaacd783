# SPDX-License-Identifier: GPL-3.0-or-later

"""The render stage: the native results of a prepared scene seen from one view, {name: array}, for F12, the
viewport's progressive steps and the command line; and what the interface estimates of a view without rendering."""

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..scene import camera, volumes
from . import cache, viewport


def native_camera(view):
    import pcvr_native
    return pcvr_native.Camera(view.world_to_camera, view.projection, view.width, view.height)


@dataclass
class Control:
    """The progress and cancel arguments of the native calls."""
    progress: object = None   # callable taking the fraction of the whole render, or None
    cancel: object = None     # callable or threading.Event, or None

    def arguments(self, threads, part=0, parts=1):
        """Keyword arguments of native call `part` of `parts`."""
        progress = self.progress
        if progress is not None and parts > 1:
            progress = lambda fraction: self.progress((part + fraction) / parts)  # noqa: E731
        return dict(progress=progress, cancel=self.cancel, threads=threads)


def _zeros(view, channels=None):
    return np.zeros((view.height, view.width) + ((channels,) if channels else ()), dtype=np.float32)


def _level_argument(level):
    """The native renderers' `level` keyword: none for their own default."""
    return {} if level is None else {"level": level}


def _xray_integral(prepared, view, control, stats, level=None):
    import pcvr_native

    grids = prepared.xray_grids
    # A share of a split frame leaves out the grids other shares render (None).
    kept = [index for index, grid in enumerate(grids) if grid is not None]
    if not kept:
        return _zeros(view)
    settings = prepared.inputs.xray
    clip = {name: None if value is None else [value[index] for index in kept]
            for name, value in prepared.clip_arguments.items()}
    return pcvr_native.render_xray(
        [grids[index] for index in kept], native_camera(view),
        method=settings.method, splat_kernel=settings.splat_kernel, post_filter=settings.post_filter,
        stride=settings.stride, passband=settings.passband,
        density_scale=[prepared.density_scales[index] for index in kept],
        attenuation=[prepared.xray_attenuation[index] for index in kept],
        stats=stats, **clip, **_level_argument(level), **control.arguments(prepared.inputs.threads))


def _render_xray(prepared, view, control, stats, sheets, level):
    return {"integral": _xray_integral(prepared, view, control, stats, level)}


def _render_shaded(prepared, view, control, stats, sheets, level):
    import pcvr_native

    with_depth = prepared.inputs.with_depth
    # A split frame's volume read whole renders in its first share only (batch.split_frame).
    left_out = prepared.share and prepared.share[0] > 0 and not prepared.brick_arguments(prepared.grids[0])
    if not prepared.volumes or left_out:
        nothing = np.full((view.height, view.width), np.inf, dtype=np.float32) if with_depth else None
        return {"rgba": _zeros(view, 4), "depth": nothing}
    transfer_functions, lights, ambient, shadings = prepared.lighting
    result = pcvr_native.render_shaded(
        prepared.grids, native_camera(view), transfer_functions, lights=lights, ambient=ambient, shading=shadings,
        stats=stats, density_scale=prepared.density_scales, albedo_grids=prepared.albedo_grids,
        return_depth=with_depth, **prepared.clip_arguments, **prepared.brick_arguments(prepared.grids[0]),
        **dataclasses.asdict(sheets), **_level_argument(level), **control.arguments(prepared.inputs.threads))
    rgba, depth = result if with_depth else (result, None)
    return {"rgba": rgba, "depth": depth}


def _render_mip(prepared, view, control, stats, sheets, level):
    import pcvr_native

    maxima = []
    for index, volume in enumerate(prepared.volumes):
        volume_stats = {}
        maxima.append(pcvr_native.render_mip(
            volume.grid, native_camera(view), density_scale=volume.inputs.density_scale, stats=volume_stats,
            **volume.inputs.clipping.native_arguments(), **sheets.mip_arguments(), **_level_argument(level),
            **prepared.brick_arguments(volume.grid),
            **control.arguments(prepared.inputs.threads, index, len(prepared.volumes))))
        _add_stats(stats, volume_stats)
    return {"maxima": maxima, "volumes": [volume.finishing for volume in prepared.volumes],
            "shape": (view.height, view.width)}


def _add_stats(total, stats):
    for key, value in stats.items():
        total[key] = total.get(key, type(value)()) + value


RENDERERS = {
    'XRAY': _render_xray,
    'SHADED': _render_shaded,
    'MIP': _render_mip,
}


def render_raw(prepared, view, control=None, stats=None, sheet_spacing_factor=1.0, level=None):
    """The native results of a PreparedScene seen by `view` (a CameraView): {"integral"}, {"rgba", "depth"} or
    {"maxima", "volumes"}, and the integral too where the XRay pass is on. `sheet_spacing_factor` times the sheet spacing
    of shaded and MIP modes, `level` the level of detail (None: the native renderers' default), for the
    viewport's coarse images. Raises pcvr_native.RenderCancelled."""
    control = Control() if control is None else control
    stats = {} if stats is None else stats
    inputs = prepared.inputs.with_sheet_spacing(sheet_spacing_factor)
    raw = RENDERERS[inputs.mode](prepared, view, control, stats, inputs.sheets, level)
    if inputs.xray is not None and "integral" not in raw:
        raw["integral"] = _xray_integral(prepared, view, control, {}, level)
    return raw


def render_viewport_step(prepared, view, step, cancel, stats=None):
    """render_raw of a viewport.Step: at 1/step.scale of the view's pixels, from the level of detail
    viewport.step_level picks, with step.sheet_spacing times the sheet spacing in voxels of level 0. None when
    `cancel` (a threading.Event) stopped it. `stats`: a dict the native renderer fills, as render_raw's."""
    import pcvr_native

    scaled = view.scaled(step.scale)
    level = viewport_step_level(prepared, view, step)
    # Native sheets are spaced in voxels of the level rendered: as far apart in level-0 voxels as the step says,
    # but never closer than one voxel of the level.
    spacing = step.sheet_spacing if level is None else max(1.0, step.sheet_spacing / 2 ** level)
    try:
        return render_raw(prepared, scaled, Control(cancel=cancel), stats=stats, sheet_spacing_factor=spacing, level=level)
    except pcvr_native.RenderCancelled:
        return None


def viewport_step_level(prepared, view, step):
    """viewport.step_level of the grids as the step's image of `view` shows them."""
    import pcvr_native

    def grids_in_view():
        camera = native_camera(view.scaled(step.scale))
        most_magnified = max(pcvr_native.effective_magnification(grid, camera)[1] for grid in prepared.grids)
        fewest_across = min(int(np.max(np.subtract(grid.index_bbox[1], grid.index_bbox[0]))) + 1
                            for grid in prepared.grids)
        return most_magnified, fewest_across

    return viewport.step_level(step, grids_in_view) if prepared.grids else None


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
        placement = volumes.placement(source.object_to_world, source.index_to_object, grid.index_to_world)
        grid = grid.with_index_to_world(placement @ grid.index_to_world)
        grid_low, grid_high = pcvr_native.effective_magnification(grid, native)
        if grid_high == 0:
            continue  # none of its blocks is in view after all
        low, high = min(low, grid_low), max(high, grid_high)
        automatic = pcvr_native.automatic_stride(grid, native)  # X-ray's; sheets take its whole part
        strides.add(settings.subgrid_stride or (automatic if settings.mode == 'XRAY' else int(automatic)))
    return ((low, high) if high else None), sorted(strides), unread
