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
"""

from dataclasses import dataclass

import numpy as np

from . import cache, camera, lighting, transfer_function, volumes
from .properties import NATIVE_NAMES, as_typed

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


@dataclass
class LoadedVolume:
    source: volumes.VolumeSource
    grid: object  # pcvr_native.Grid in world space

    @property
    def settings(self):
        return self.source.volume.pcvr


@dataclass
class Frame:
    """What every mode's renderer needs."""
    engine: object
    depsgraph: object
    view: camera.CameraView
    volumes: list

    @property
    def scene(self):
        return self.depsgraph.scene

    @property
    def grids(self):
        return [volume.grid for volume in self.volumes]

    @property
    def density_scales(self):
        return [volume.source.density_scale for volume in self.volumes]

    def zeros(self, channels=None):
        shape = (self.view.height, self.view.width) + ((channels,) if channels else ())
        return np.zeros(shape, dtype=np.float32)

    def control(self, part=0, parts=1):
        """progress, cancel and threads arguments; progress of call `part` of `parts`."""
        update = self.engine.update_progress
        return dict(progress=lambda fraction: update((part + fraction) / parts), cancel=self.engine.test_break,
                    threads=self.scene.render.threads)


def render(engine, depsgraph):
    import pcvr_native

    view = camera.render_view(engine, depsgraph)
    if view is None:
        _fail(engine, "PCVR: the scene has no camera")
        return

    loaded = _load_volumes(engine, depsgraph, view)
    if engine.test_break():
        return

    frame = Frame(engine, depsgraph, view, loaded)
    mode = depsgraph.scene.pcvr.mode
    engine.update_stats("", "Rendering")
    stats = {}
    try:
        pixels = RENDERERS[mode](frame, stats)
        if depsgraph.view_layer.pcvr.use_pass_xray and "XRay" not in pixels:
            pixels["XRay"] = _xray_integral(frame, {})[:, :, None]
    except pcvr_native.RenderCancelled:
        return
    except (MemoryError, ValueError, RuntimeError) as ex:  # RuntimeError: any other native error
        _fail(engine, f"PCVR: {ex}")
        return

    _write_result(engine, depsgraph, view, pixels)
    last_render[depsgraph.scene.session_uid] = (mode, stats)
    engine.update_stats("", format_stats(stats) if mode == 'XRAY' else format_sheet_stats(stats))


def _load_volumes(engine, depsgraph, view):
    """The volumes in view with their world-space grids. A volume that cannot be read is reported and
    left out; the others still render."""
    loaded, errors = [], []
    for source in volumes.in_view(depsgraph, view):
        if engine.test_break():
            break
        engine.update_stats("", f"Reading {source.name}")
        try:
            loaded.append(LoadedVolume(source, load_grid(source)))
        except (OSError, ValueError, RuntimeError, MemoryError) as ex:
            errors.append(f"Volume object '{source.name}': {ex}")
    _report_errors(engine, errors)
    return loaded


def _report_errors(engine, errors):
    for message in errors:
        engine.report({'ERROR'}, message)
    if errors:
        engine.error_set("\n".join(errors))


def _fail(engine, message):
    engine.report({'ERROR'}, message)
    engine.error_set(message)


# -------------------------------------------------------------------------------------------------
# X-ray

def _xray_integral(frame, stats):
    import pcvr_native

    if not frame.volumes:
        return frame.zeros()
    settings = frame.scene.pcvr
    return pcvr_native.render_xray(
        frame.grids, native_camera(frame.view),
        method=NATIVE_NAMES[settings.method],
        splat_kernel=NATIVE_NAMES[settings.splat_kernel],
        post_filter=NATIVE_NAMES[settings.post_filter],
        stride=settings.subgrid_stride,
        density_scale=frame.density_scales,
        stats=stats,
        **frame.control(),
    )


def pass_pixels(settings, film_transparent, integral):
    """The pixels of every pass from the line integral: {name: float32 (height, width, channels)}."""
    height, width = integral.shape
    combined = np.empty((height, width, 4), dtype=np.float32)
    combined[:, :, :3] = (-np.expm1(-settings.xray_gain * integral))[:, :, None]
    combined[:, :, 3] = (integral != 0) if film_transparent else 1.0
    return {"Combined": combined, "XRay": integral[:, :, None]}


def _render_xray(frame, stats):
    return pass_pixels(frame.scene.pcvr, frame.scene.render.film_transparent, _xray_integral(frame, stats))


# -------------------------------------------------------------------------------------------------
# Shaded and MIP: the sheet renderers

def _sheet_arguments(settings):
    return dict(
        method=NATIVE_NAMES[settings.method],
        splat_kernel=NATIVE_NAMES[settings.splat_kernel],
        post_filter=NATIVE_NAMES[settings.sheet_post_filter],
        stride=settings.subgrid_stride,
        sheet_spacing=as_typed(settings.sheet_spacing),
    )


def density_range(volume):
    """The densities a LoadedVolume's ramp spans: (tf_min, tf_max), or its grid's."""
    return transfer_function.density_range(volume.settings, volume.grid.value_range, volume.source.density_scale)


def control_points(volume):
    """The transfer function of a LoadedVolume as ControlPoints over its density range. ValueError names
    the volume."""
    settings = volume.settings
    low, high = density_range(volume)
    try:
        return transfer_function.control_points(settings.ramp, low, high)
    except ValueError as ex:
        raise ValueError(f"Volume object '{volume.source.name}': {ex}") from None


def native_transfer_function(volume):
    """pcvr_native.TransferFunction of a LoadedVolume."""
    import pcvr_native

    points = control_points(volume)
    unit_distance = transfer_function.smallest_voxel_spacing(volume.grid.index_to_world) / volume.settings.opacity_scale
    return pcvr_native.TransferFunction(points.density, points.rgba, unit_distance=unit_distance)


def material(settings):
    """A volume's material: (use_shading, ambient, diffuse, specular, shininess)."""
    return (settings.use_shading, *(as_typed(getattr(settings, name))
                                    for name in ("ambient", "diffuse", "specular", "shininess")))


def native_lighting(frame):
    """(lights, ambient colour, one Shading per volume) for render_shaded: the scene's lights and world, and
    each volume's material. A volume without shading shows its transfer function's colours."""
    import pcvr_native

    shadings = []
    for volume in frame.volumes:
        use_shading, ambient, diffuse, specular, shininess = material(volume.settings)
        shadings.append(pcvr_native.Shading(ambient=ambient, diffuse=diffuse, specular=specular,
                                            shininess=shininess, lit=use_shading))
    lights = []
    for spec in lighting.scene_lights(frame.depsgraph):
        make = pcvr_native.Light.sun if spec.kind == "sun" else pcvr_native.Light.point
        lights.append(make(spec.vector, color=spec.color, strength=spec.strength))
    return lights, lighting.world_colour(frame.scene.world), shadings


def over_background(rgba, world, film_transparent):
    """Premultiplied `rgba` over the world colour, or as it is with a transparent film."""
    if film_transparent:
        return rgba
    combined = rgba.copy()
    combined[:, :, :3] += (1.0 - rgba[:, :, 3:]) * np.asarray(world, dtype=np.float32)
    combined[:, :, 3] = 1.0
    return combined


def _render_shaded(frame, stats):
    import pcvr_native

    settings = frame.scene.pcvr
    with_depth = frame.depsgraph.view_layer.use_pass_z
    rgba, depth = frame.zeros(4), np.full((frame.view.height, frame.view.width), np.inf, dtype=np.float32)
    if frame.volumes:
        lights, ambient, shading = native_lighting(frame)
        result = pcvr_native.render_shaded(
            frame.grids, native_camera(frame.view), [native_transfer_function(v) for v in frame.volumes],
            lights=lights, ambient=ambient, shading=shading,
            opacity_cutoff=as_typed(settings.opacity_cutoff), stats=stats,
            density_scale=frame.density_scales, samples_per_sheet=settings.samples_per_sheet,
            return_depth=with_depth, **_sheet_arguments(settings), **frame.control())
        rgba, depth = result if with_depth else (result, depth)
    world = lighting.world_colour(frame.scene.world)
    pixels = {"Combined": over_background(rgba, world, frame.scene.render.film_transparent)}
    if with_depth:
        pixels["Depth"] = np.where(np.isfinite(depth), depth, BACKGROUND_DEPTH).astype(np.float32)[:, :, None]
    return pixels


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


def _render_mip(frame, stats):
    """Each volume's maximum through its own transfer function; where volumes overlap on the image, the
    brighter of their colours in each channel (a maximum of the colours, as the mode's name says)."""
    import pcvr_native

    settings = frame.scene.pcvr
    rgba = frame.zeros(4)
    for index, volume in enumerate(frame.volumes):
        points = control_points(volume)
        volume_stats = {}
        maximum = pcvr_native.render_mip(
            volume.grid, native_camera(frame.view), density_scale=volume.source.density_scale,
            stats=volume_stats, **_sheet_arguments(settings), **frame.control(index, len(frame.volumes)))
        background = volume.grid.background * volume.source.density_scale
        np.maximum(rgba, mip_colours(maximum, points, density_range(volume), settings.mip_color, background), out=rgba)
        _add_stats(stats, volume_stats)
    world = lighting.world_colour(frame.scene.world)
    return {"Combined": over_background(rgba, world, frame.scene.render.film_transparent)}


def _add_stats(total, stats):
    for key, value in stats.items():
        total[key] = total.get(key, type(value)()) + value


RENDERERS = {
    'XRAY': _render_xray,
    'SHADED': _render_shaded,
    'MIP': _render_mip,
}


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

def format_stats(stats):
    """One line for the status bar from render_xray's statistics."""
    if not stats:
        return "No volume in view"
    low, high = stats["magnification"], stats["magnification_max"]
    magnification = f"{low:.2f}" if high - low < 0.005 else f"{low:.2f}-{high:.2f}"
    strides = ", ".join(str(stride) for stride in stats["strides"]) or "-"
    return (f"Voxels {stats['voxels']:,} | Magnification {magnification} px/voxel | Stride {strides} | "
            f"Time {stats['seconds']:.2f} s")


def format_sheet_stats(stats):
    """One line for the status bar from render_shaded's or render_mip's statistics."""
    if not stats:
        return "No volume in view"
    culled = stats["blocks_outside"] + stats["blocks_transparent"]
    strides = ", ".join(str(stride) for stride in stats["strides"]) or "-"
    return (f"Voxels {stats['voxels']:,} | Culled blocks {culled:,} of {stats['blocks']:,} | "
            f"Sheets {stats['sheets']:,} | Stride {strides} | Time {stats['seconds']:.2f} s")


def _share(part, whole):
    return f"{part:,} ({100 * part / whole:.0f}%)" if whole else f"{part:,}"


def statistics_rows(mode, stats):
    """(label, value) rows of a render's statistics, for the interface."""
    if not stats:
        return [("Volumes", "none in view")]
    if mode == 'XRAY':
        return [("Voxels", f"{stats['voxels']:,}"),
                ("Magnification", f"{stats['magnification']:.2f} - {stats['magnification_max']:.2f} px/voxel"),
                ("Stride", ", ".join(map(str, stats["strides"])) or "-"),
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
        ("Stride", ", ".join(map(str, stats["strides"])) or "-"),
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
        strides.add(settings.subgrid_stride or pcvr_native.automatic_stride(grid, native))
    return ((low, high) if high else None), sorted(strides), unread
