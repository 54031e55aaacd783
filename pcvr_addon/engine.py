# SPDX-License-Identifier: GPL-3.0-or-later

"""Rendering: the one module that talks to pcvr_native (imported inside functions, so that the add-on
registers, and its settings can be edited, even where the native module cannot load).

| mode     | pcvr_native call      | Combined pass                                                        |
|----------|-----------------------|----------------------------------------------------------------------|
| X-Ray    | render_xray           | 1 - exp(-gain * integral) in grey                                    |
| Shaded   | render_shaded         | premultiplied RGBA over the world colour (or transparent)            |
| MIP      | render_mip per volume | the largest density through the transfer function's colours, or grey |

Passes: Combined always; Depth in shaded mode with the view layer's Z pass (where opacity first reaches one
half; background 1e10, as Cycles writes it); XRay with the view layer's PCVR X-ray pass, in every mode.

A render goes through four stages, so that the viewport can run the last three on a worker thread (where
Blender's data must not be touched) and repeat only those that a change reaches:

| stage   | function               | runs on                | gives                                              |
|---------|------------------------|------------------------|----------------------------------------------------|
| read    | scene_inputs.read      | Blender's main thread  | the scene as plain values                          |
| prepare | prepare                | any thread             | world-space grids (through the cache), transfer functions, lights |
| render  | render_raw             | any thread             | the native results: integral, RGBA and depth, maxima |
| finish  | finish                 | any thread             | the passes                                         |
"""

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from . import cache, camera, scene_inputs, transfer_function, viewport, volumes

# Depth where a ray meets nothing opaque enough: what Cycles and Workbench write for the background.
BACKGROUND_DEPTH = 1e10

# The statistics of the last render of each scene, for the interface: {scene.session_uid: (mode, stats)}
# (session_uid: unique in this Blender session, so a scene of another file never shows these).
last_render = {}


def list_render_passes(scene, view_layer):
    """The passes of a render: (name, channel ids, channel type)."""
    yield ("Combined", "RGBA", 'COLOR')
    if scene.pcvr.mode == 'SHADED' and view_layer.use_pass_z:
        yield ("Depth", "Z", 'VALUE')
    if view_layer.pcvr.use_pass_xray:
        yield ("XRay", "X", 'VALUE')


def register_passes(engine, scene, view_layer):
    for name, channel_ids, channel_type in list_render_passes(scene, view_layer):
        engine.register_pass(scene, view_layer, name, len(channel_ids), channel_ids, channel_type)


def read_grid(filepath, grid_name):
    import pcvr_native
    return pcvr_native.read_vdb(filepath, grid_name)


def stream_grid(filepath, grid_name):
    import pcvr_native
    return pcvr_native.stream_vdb(filepath, grid_name)


MiB = 1 << 20


def stream_threshold(stream_above_mib):
    """Bytes of voxel values above which a volume is streamed (RenderInputs.stream_above_mib), or None."""
    import pcvr_native

    if stream_above_mib is None:
        return None
    return stream_above_mib * MiB if stream_above_mib > 0 else pcvr_native.default_memory_limit() // 4


def value_bytes(filepath, grid_name):
    """The bytes a file's grid takes read whole, from its metadata (read_vdb's choice when `grid_name` is
    None); 0 when the file does not say."""
    import pcvr_native

    grids = pcvr_native.list_grids(filepath)
    chosen = [g for g in grids if g["name"] == (grid_name or "density")] or grids[:1]
    return 4 * chosen[0]["active_voxels"] if chosen else 0


def export_grid(source):
    """The grid of a procedural VolumeSource (made or changed by modifiers), through a temporary file.
    Blender's data: call on its main thread."""
    with volumes.exported_grids(source.volume) as filepath:
        return read_grid(filepath, source.grid_name)


def load_grid(source):
    """The grid of a VolumeSource in world space. Raises OSError or ValueError naming the cause."""
    if source.error:
        raise OSError(source.error)
    grid = cache.grids.get(source.filepath, source.grid_name, read_grid) if source.filepath else export_grid(source)
    return grid.with_index_to_world(source.object_to_world @ grid.index_to_world)


def native_camera(view):
    import pcvr_native
    return pcvr_native.Camera(view.world_to_camera, view.projection, view.width, view.height)


# -------------------------------------------------------------------------------------------------
# Prepare

@dataclass
class LoadedVolume:
    index: int                          # in RenderInputs.volumes
    inputs: scene_inputs.VolumeInputs
    grid: object                        # pcvr_native.Grid in world space (X-ray: or a GridStream)
    # Shaded and MIP of a volume too big to read whole: the GridStream its grid is level `level` of.
    stream: object = None
    level: int = 0

    @property
    def value_range(self):
        """The densities of the volume itself (a coarse level's means span less)."""
        return (self.stream or self.grid).value_range

    @property
    def xray_grid(self):
        """What an X-ray of it renders: the stream where there is one (its levels keep line integrals)."""
        return self.stream or self.grid


@dataclass
class PreparedScene:
    """RenderInputs with their grids read and their native objects made: what every render of them, from any
    view, re-uses."""
    inputs: scene_inputs.RenderInputs
    volumes: list                       # LoadedVolume
    errors: list = field(default_factory=list)    # volumes that could not be read, one message each
    lighting: tuple = ()                # shaded: (transfer functions, lights, ambient, Shading)
    warnings: list = field(default_factory=list)  # volumes rendered from a coarse level, one message each

    @property
    def grids(self):
        return [volume.grid for volume in self.volumes]

    @property
    def xray_grids(self):
        return [volume.xray_grid for volume in self.volumes]

    @property
    def density_scales(self):
        return [volume.inputs.density_scale for volume in self.volumes]

    @property
    def streamed(self):
        """How many volumes are read from their files while rendering (X-ray of big volumes)."""
        import pcvr_native
        return sum(isinstance(volume.grid, pcvr_native.GridStream) for volume in self.volumes)


# The levels shaded and MIP modes draw a streamed volume from: means over the background (what they reconstruct
# towards), and MIP's maxima (a mean is lower than the largest value it stands for).
LEVEL_REDUCTIONS = {'SHADED': "mean_over_background", 'MIP': "max_over_background"}


def fitting_level(value_bytes, budget):
    """The finest level of detail (1 to 7) whose voxels take at most `budget` bytes."""
    level = 1
    while level < 7 and value_bytes >> (3 * level) > budget:
        level += 1
    return level


def _grid(volume, stream_above=None):
    """A VolumeInputs' grid: a pcvr_native.GridStream when its file's values take more than `stream_above`
    bytes and it can be streamed (float fog volumes), else the Grid read whole."""
    import pcvr_native

    if volume.error:
        raise OSError(volume.error)
    if volume.grid is not None:
        return volume.grid
    if stream_above is not None and value_bytes(volume.filepath, volume.grid_name) > stream_above:
        try:
            return cache.grids.get(volume.filepath, volume.grid_name, stream_grid, kind="stream")
        except pcvr_native.GridError:
            pass  # a double grid, a level set: converted as a whole
    return cache.grids.get(volume.filepath, volume.grid_name, read_grid)


def prepare(inputs, cancelled=lambda: False, reading=lambda name: None):
    """PreparedScene of RenderInputs. A volume that cannot be read is left out with a message in `errors`;
    `reading(name)` is told of each volume before it is read; a true `cancelled()` stops reading. Raises
    ValueError for a transfer function without a range."""
    import pcvr_native

    loaded, errors, warnings = [], [], []
    stream_above = stream_threshold(inputs.stream_above_mib)
    for index, volume in enumerate(inputs.volumes):
        if cancelled():
            break
        reading(volume.name)
        try:
            grid = _grid(volume, stream_above)
            stream, level = None, 0
            if isinstance(grid, pcvr_native.GridStream) and inputs.mode in LEVEL_REDUCTIONS:
                # Shaded and MIP need every voxel at once: the finest level that fits stands in for the volume.
                stream, level = grid, fitting_level(grid.value_bytes, stream_above)
                grid = stream.level(level, LEVEL_REDUCTIONS[inputs.mode])
                warnings.append(f"Volume object '{volume.name}': {stream.value_bytes / MiB:,.0f} MiB of voxels, more "
                                f"than Stream Above: rendered from level {level} of detail (1/{2 ** level} of its "
                                "resolution)")
        except (OSError, ValueError, RuntimeError, MemoryError) as ex:
            errors.append(f"Volume object '{volume.name}': {ex}")
            continue
        placed = [None if g is None else g.with_index_to_world(volume.matrix @ g.index_to_world) for g in (grid, stream)]
        loaded.append(LoadedVolume(index, volume, placed[0], placed[1], level))
    prepared = PreparedScene(inputs, loaded, errors, warnings=warnings)
    if inputs.mode == 'SHADED' and loaded:
        prepared.lighting = _native_lighting(prepared)
    return prepared


def density_range(ramp, volume):
    """The densities a LoadedVolume's ramp (RampInputs) spans: (tf_min, tf_max), or its grid's."""
    return transfer_function.density_range(ramp, volume.value_range, volume.inputs.density_scale)


def control_points(ramp, volume):
    """A LoadedVolume's ramp (RampInputs) as ControlPoints over its density range. ValueError names the
    volume."""
    low, high = density_range(ramp, volume)
    try:
        return transfer_function.points_over_range(ramp.positions, ramp.rgba, low, high)
    except ValueError as ex:
        raise ValueError(f"Volume object '{volume.inputs.name}': {ex}") from None


def native_transfer_function(volume):
    """pcvr_native.TransferFunction of a LoadedVolume in shaded mode."""
    import pcvr_native

    ramp = volume.inputs.ramp
    points = control_points(ramp, volume)
    # The opacity's unit is the volume's own voxel, also where a coarser level stands in for it.
    voxel = transfer_function.smallest_voxel_spacing(volume.grid.index_to_world) / 2 ** volume.level
    unit_distance = voxel / ramp.opacity_scale
    return pcvr_native.TransferFunction(points.density, points.rgba, unit_distance=unit_distance)


def _native_lighting(prepared):
    """(transfer functions, lights, ambient colour, one Shading per volume) for render_shaded: the scene's lights
    and world, and each volume's material. A volume without shading shows its transfer function's colours."""
    import pcvr_native

    transfer_functions = [native_transfer_function(volume) for volume in prepared.volumes]
    shadings = []
    for volume in prepared.volumes:
        use_shading, ambient, diffuse, specular, shininess = volume.inputs.material
        shadings.append(pcvr_native.Shading(ambient=ambient, diffuse=diffuse, specular=specular,
                                            shininess=shininess, lit=use_shading))
    lights = []
    for spec in prepared.inputs.lights:
        make = pcvr_native.Light.sun if spec.kind == "sun" else pcvr_native.Light.point
        lights.append(make(spec.vector, color=spec.color, strength=spec.strength))
    return transfer_functions, lights, prepared.inputs.world, shadings


# -------------------------------------------------------------------------------------------------
# Render: native results, {name: array}

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

    if not prepared.volumes:
        return _zeros(view)
    settings = prepared.inputs.xray
    return pcvr_native.render_xray(
        prepared.xray_grids, native_camera(view),
        method=settings.method, splat_kernel=settings.splat_kernel, post_filter=settings.post_filter,
        stride=settings.stride, density_scale=prepared.density_scales, stats=stats,
        **_level_argument(level), **control.arguments(prepared.inputs.threads))


def _render_xray(prepared, view, control, stats, sheets, level):
    return {"integral": _xray_integral(prepared, view, control, stats, level)}


def _render_shaded(prepared, view, control, stats, sheets, level):
    import pcvr_native

    with_depth = prepared.inputs.with_depth
    if not prepared.volumes:
        nothing = np.full((view.height, view.width), np.inf, dtype=np.float32) if with_depth else None
        return {"rgba": _zeros(view, 4), "depth": nothing}
    transfer_functions, lights, ambient, shadings = prepared.lighting
    result = pcvr_native.render_shaded(
        prepared.grids, native_camera(view), transfer_functions, lights=lights, ambient=ambient, shading=shadings,
        stats=stats, density_scale=prepared.density_scales, return_depth=with_depth,
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
            **sheets.mip_arguments(), **_level_argument(level),
            **control.arguments(prepared.inputs.threads, index, len(prepared.volumes))))
        _add_stats(stats, volume_stats)
    return {"maxima": maxima, "shape": (view.height, view.width)}


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
    {"maxima"}, and the integral too where the XRay pass is on. `sheet_spacing_factor` times the sheet spacing
    of shaded and MIP modes, `level` the level of detail (None: the native renderers' default), for the
    viewport's coarse images. Raises pcvr_native.RenderCancelled."""
    control = Control() if control is None else control
    stats = {} if stats is None else stats
    inputs = prepared.inputs.with_sheet_spacing(sheet_spacing_factor)
    raw = RENDERERS[inputs.mode](prepared, view, control, stats, inputs.sheets, level)
    if inputs.xray is not None and "integral" not in raw:
        raw["integral"] = _xray_integral(prepared, view, control, {}, level)
    return raw


# -------------------------------------------------------------------------------------------------
# Finish: {pass name: float32 (height, width, channels)}

def pass_pixels(gain, film_transparent, integral):
    """The pixels of every pass from the line integral: {name: float32 (height, width, channels)}."""
    height, width = integral.shape
    combined = np.empty((height, width, 4), dtype=np.float32)
    combined[:, :, :3] = (-np.expm1(-gain * integral))[:, :, None]
    combined[:, :, 3] = (integral != 0) if film_transparent else 1.0
    return {"Combined": combined, "XRay": integral[:, :, None]}


def over_background(rgba, world, film_transparent):
    """Premultiplied `rgba` over the world colour, or as it is with a transparent film."""
    if film_transparent:
        return rgba
    combined = rgba.copy()
    combined[:, :, :3] += (1.0 - rgba[:, :, 3:]) * np.asarray(world, dtype=np.float32)
    combined[:, :, 3] = 1.0
    return combined


def mip_colours(maximum, points, density_range, mip_color, background=0.0):
    """Premultiplied RGBA of a volume's MIP: through the transfer function's colours (ControlPoints), or grey
    from black at the low end of its density range to white at the high end; alpha 1 where a voxel reaches
    (the maximum is not the grid's scaled background, which rays that meet no voxel return)."""
    reached = maximum != np.float32(background)
    if mip_color == 'GREYSCALE':
        low, high = density_range
        rgb = np.repeat(np.clip((maximum - low) / (high - low), 0.0, 1.0)[:, :, None], 3, axis=2)
    else:
        rgb = points.colour_at(maximum)[:, :, :3]
    rgba = np.concatenate([rgb * reached[:, :, None], reached[:, :, None]], axis=2)
    return rgba.astype(np.float32)


def _finish_xray(prepared, display, raw):
    return pass_pixels(display.xray_gain, display.film_transparent, raw["integral"])


def _finish_shaded(prepared, display, raw):
    pixels = {"Combined": over_background(raw["rgba"], display.world, display.film_transparent)}
    if raw["depth"] is not None:
        depth = raw["depth"]
        pixels["Depth"] = np.where(np.isfinite(depth), depth, BACKGROUND_DEPTH).astype(np.float32)[:, :, None]
    return pixels


def _finish_mip(prepared, display, raw):
    """Each volume's maximum through its own transfer function; where volumes overlap on the image, the
    brighter of their colours in each channel (a maximum of the colours, as the mode's name says)."""
    rgba = None
    for volume, maximum in zip(prepared.volumes, raw["maxima"]):
        ramp = display.ramps[volume.index]
        background = volume.grid.background * volume.inputs.density_scale
        colours = mip_colours(maximum, control_points(ramp, volume), density_range(ramp, volume), display.mip_color,
                              background)
        rgba = colours if rgba is None else np.maximum(rgba, colours)
    if rgba is None:
        rgba = np.zeros(raw["shape"] + (4,), dtype=np.float32)
    return {"Combined": over_background(rgba, display.world, display.film_transparent)}


FINISHERS = {
    'XRAY': _finish_xray,
    'SHADED': _finish_shaded,
    'MIP': _finish_mip,
}


def finish(prepared, display, raw):
    """The passes of native results `raw` under DisplayInputs: {name: float32 (height, width, channels)}."""
    pixels = FINISHERS[display.mode](prepared, display, raw)
    if "integral" in raw and "XRay" not in pixels:
        pixels["XRay"] = raw["integral"][:, :, None]
    return pixels


# -------------------------------------------------------------------------------------------------
# The viewport's stages (viewport.ProgressiveRenderer runs them on its worker thread)

def render_viewport_step(prepared, view, step, cancel):
    """render_raw of a viewport.Step: at 1/step.scale of the view's pixels, from the level of detail
    viewport.step_level picks, with step.sheet_spacing times the sheet spacing in voxels of level 0. None when
    `cancel` (a threading.Event) stopped it."""
    import pcvr_native

    scaled = view.scaled(step.scale)
    level = viewport_step_level(prepared, view, step)
    # Native sheets are spaced in voxels of the level rendered: as far apart in level-0 voxels as the step says,
    # but never closer than one voxel of the level.
    spacing = step.sheet_spacing if level is None else max(1.0, step.sheet_spacing / 2 ** level)
    try:
        return render_raw(prepared, scaled, Control(cancel=cancel), sheet_spacing_factor=spacing, level=level)
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


def viewport_pixels(prepared, display, raw):
    """The Combined pass of a viewport render."""
    return finish(prepared, display, raw)["Combined"]


# -------------------------------------------------------------------------------------------------
# F12

def render(engine, depsgraph):
    import pcvr_native

    view = camera.render_view(engine, depsgraph)
    if view is None:
        _fail(engine, "PCVR: the scene has no camera")
        return

    inputs, display = scene_inputs.read(depsgraph, export_grid, view)
    try:
        prepared = prepare(inputs, engine.test_break, lambda name: engine.update_stats("", f"Reading {name}"))
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
        raw = render_raw(prepared, view, Control(ProgressReport(engine, voxels), engine.test_break), stats)
    except pcvr_native.RenderCancelled:
        return
    except (MemoryError, ValueError, RuntimeError) as ex:  # RuntimeError: any other native error
        _fail(engine, f"PCVR: {ex}")
        return

    _write_result(engine, depsgraph, view, finish(prepared, display, raw))
    if prepared.streamed:
        stats["streamed"] = prepared.streamed
    stream_level = max((volume.level for volume in prepared.volumes), default=0)
    if stream_level:
        stats["level"] = stats.get("level", 0) + stream_level  # of the volume itself, not of its level
    last_render[depsgraph.scene.session_uid] = (inputs.mode, stats)
    engine.update_stats("", status_line(inputs.mode, stats))


def _report_errors(engine, errors):
    for message in errors:
        engine.report({'ERROR'}, message)
    if errors:
        engine.error_set("\n".join(errors))


def _fail(engine, message):
    engine.report({'ERROR'}, message)
    engine.error_set(message)


def _write_result(engine, depsgraph, view, pixels):
    view_layer = depsgraph.view_layer
    # Result coordinates start at the render border, when there is one.
    result = engine.begin_result(0, 0, view.width, view.height, layer=view_layer.name)
    layer = result.layers[0]
    for name, _channel_ids, _channel_type in list_render_passes(depsgraph.scene, view_layer):
        # Blender stores rows bottom to top.
        rect = np.ascontiguousarray(pixels[name][::-1], dtype=np.float32)
        layer.passes[name].rect.foreach_set(rect.ravel())
    engine.end_result(result)


# -------------------------------------------------------------------------------------------------
# Statistics

def format_strides(strides):
    """Subgrid strides for display: X-ray strides are pixels between nodes and need not be whole."""
    return ", ".join(f"{stride:.2f}".rstrip("0").rstrip(".") for stride in strides) or "-"


class ProgressReport:
    """The progress callback of an F12 render: Blender's progress bar, and a status line with the voxels
    splatted so far (X-ray, where the native progress runs over them) and an estimate of the time left."""

    INTERVAL = 0.25  # seconds between status lines

    def __init__(self, engine, voxels=None, clock=time.monotonic):
        self.engine, self.voxels, self.clock = engine, voxels, clock
        self.start = clock()
        self.shown = None

    def __call__(self, fraction):
        self.engine.update_progress(fraction)
        now = self.clock()
        if self.shown is not None and now - self.shown < self.INTERVAL:
            return
        self.shown = now
        self.engine.update_stats("", progress_line(fraction, now - self.start, self.voxels))


def progress_line(fraction, elapsed, voxels=None):
    """"Splatting 12.3M of 134.2M voxels | 4 s left": the status line of a render `fraction` done after
    `elapsed` seconds (the time left extrapolated once 2% is done)."""
    done = f"Splatting {_millions(fraction * voxels)} of {_millions(voxels)} voxels" if voxels \
        else f"Rendering {100 * fraction:.0f}%"
    if fraction < 0.02 or fraction >= 1:
        return done
    return f"{done} | {elapsed * (1 - fraction) / fraction:.0f} s left"


def _millions(count):
    return f"{count / 1e6:.1f}M"


def format_stats(stats):
    """One line for the status bar from render_xray's statistics."""
    if not stats:
        return "No volume in view"
    low, high = stats["magnification"], stats["magnification_max"]
    magnification = f"{low:.2f}" if high - low < 0.005 else f"{low:.2f}-{high:.2f}"
    strides = format_strides(stats["strides"])
    streamed = ""
    if stats.get("streamed"):
        count, batches = stats["streamed"], stats["batches"]
        streamed = (f" | Streamed {count} volume{'s' if count > 1 else ''} from "
                    f"{'their files' if count > 1 else 'its file'} in {batches} batch{'es' if batches > 1 else ''}")
    return (f"Voxels {stats['voxels']:,} | Magnification {magnification} px/voxel | Stride {strides} | "
            f"Time {stats['seconds']:.2f} s{streamed}")


def status_line(mode, stats):
    """The status bar's line after a render in `mode` with the native statistics `stats`."""
    return format_stats(stats) if mode == 'XRAY' else format_sheet_stats(stats)


def format_sheet_stats(stats):
    """One line for the status bar from render_shaded's or render_mip's statistics."""
    if not stats:
        return "No volume in view"
    culled = stats["blocks_outside"] + stats["blocks_transparent"]
    strides = format_strides(stats["strides"])
    level = f" | Level of detail {stats['level']}" if stats.get("level") else ""
    return (f"Voxels {stats['voxels']:,} | Culled blocks {culled:,} of {stats['blocks']:,} | "
            f"Sheets {stats['sheets']:,} | Stride {strides} | Time {stats['seconds']:.2f} s{level}")


def _share(part, whole):
    return f"{part:,} ({100 * part / whole:.0f}%)" if whole else f"{part:,}"


def statistics_rows(mode, stats):
    """(label, value) rows of a render's statistics, for the interface."""
    if not stats:
        return [("Volumes", "none in view")]
    if mode == 'XRAY':
        return [("Voxels", f"{stats['voxels']:,}"),
                ("Magnification", f"{stats['magnification']:.2f} - {stats['magnification_max']:.2f} px/voxel"),
                ("Stride", format_strides(stats["strides"])),
                ("Time", f"{stats['seconds']:.3f} s")]
    seconds = [("Planning", "seconds_plan"), ("Splatting", "seconds_splat"),
               ("Post-convolution", "seconds_post_convolution"), ("Shading", "seconds_shading")]
    return [
        ("Blocks", f"{stats['blocks']:,}"),
        ("Outside view", _share(stats["blocks_outside"], stats["blocks"])),
        ("Transparent", _share(stats["blocks_transparent"], stats["blocks"])),
        ("Voxels splatted", f"{stats['voxels']:,}"),
        ("Behind opaque", _share(stats["voxels_occluded"], stats["voxels"] + stats["voxels_occluded"])),
        ("Sheets", f"{stats['sheets']:,}"),
        ("Tiles finished early", _share(stats["tiles_terminated"], stats["tiles"])),
        ("Empty tile sheets", _share(stats["tile_sheets_skipped"],
                                     stats["tile_sheets_skipped"] + stats["tile_sheets_composited"])),
        ("Stride", format_strides(stats["strides"])),
        ("Time", f"{stats['seconds']:.3f} s"),
    ] + [(label, f"{stats[key]:.3f} s (threads)") for label, key in seconds]


# -------------------------------------------------------------------------------------------------
# For the interface and operators

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
        automatic = pcvr_native.automatic_stride(grid, native)  # X-ray's; sheets take its whole part
        strides.add(settings.subgrid_stride or (automatic if settings.mode == 'XRAY' else int(automatic)))
    return ((low, high) if high else None), sorted(strides), unread
