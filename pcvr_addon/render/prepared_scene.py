# SPDX-License-Identifier: GPL-3.0-or-later

"""The prepare stage: a scene's volumes read (through the cache, streamed where too big to read whole) and placed
in world space, with their transfer functions, lights and materials made into pcvr_native objects. What every
render of the scene re-uses, from any view; it runs on any thread (Blender's data was read before, by
scene.scene_inputs.read)."""

import dataclasses
from dataclasses import dataclass, field

from ..scene import clipping, scene_inputs, transfer_function, volume_material, volumes
from . import cache

def read_grid(filepath, grid_name):
    import pcvr_native
    return pcvr_native.read_vdb(filepath, grid_name)


def read_vector_grid(filepath, grid_name):
    import pcvr_native
    return pcvr_native.read_vdb_vector(filepath, grid_name)


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


def grid_entry(filepath, grid_name):
    """pcvr_native.list_grids' entry of the grid read_vdb reads (`grid_name`, or None: 'density', else the first);
    None for a file without grids."""
    import pcvr_native

    grids = pcvr_native.list_grids(filepath)
    chosen = [g for g in grids if g["name"] == (grid_name or "density")] or grids[:1]
    return chosen[0] if chosen else None


def value_bytes(filepath, grid_name):
    """The bytes a file's grid takes read whole, from its metadata (read_vdb's choice when `grid_name` is
    None); 0 when the file does not say."""
    entry = grid_entry(filepath, grid_name)
    return 4 * entry["active_voxels"] if entry else 0


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


@dataclass
class LoadedVolume:
    index: int                          # in RenderInputs.volumes
    inputs: scene_inputs.VolumeInputs
    grid: object                        # pcvr_native.Grid in world space (X-ray: or a GridStream)
    # Shaded and MIP of a volume too big to read whole: the GridStream its grid is level `level` of.
    stream: object = None
    level: int = 0
    # Shaded mode with a material whose Color Attribute names a vector grid: its (red, green, blue) Grids, placed
    # and at the grid's level, which render_shaded's albedo_grids multiplies the colour by.
    albedo_grids: tuple | None = None

    @property
    def value_range(self):
        """The densities of the volume itself (a coarse level's means span less)."""
        return (self.stream or self.grid).value_range

    # Hounsfield units: the map to linear attenuation per world unit, and the grid it maps once (set by prepare).
    attenuation: object = None          # pcvr_native.AttenuationMap
    attenuated: object = None           # pcvr_native.Grid

    @property
    def xray_grid(self):
        """What an X-ray of it renders: the stream where there is one (its levels keep line integrals), else the
        grid, in attenuation where its values are Hounsfield units."""
        return self.stream or self.attenuated or self.grid

    @property
    def xray_attenuation(self):
        """The attenuation map render_xray applies itself: a stream's, whose batches it maps as it reads them."""
        return self.attenuation if self.attenuated is None else None

    @property
    def finishing(self):
        """What finishing its passes needs of it: a FinishingVolume."""
        return FinishingVolume(self.index, self.inputs, self.value_range,
                               self.grid.background * self.inputs.density_scale)


@dataclass(frozen=True)
class FinishingVolume:
    """What the finish stage needs of a LoadedVolume, without its grid: MIP colours a volume's maxima over its
    densities' range, rays that meet no voxel return its background. Small and picklable, it travels with the native
    results, so that a split frame's finishing task (batch.split_frame) reads no volume again."""
    index: int                          # in RenderInputs.volumes
    inputs: scene_inputs.VolumeInputs
    value_range: tuple
    background: float                   # the grid's background times its density scale


@dataclass
class PreparedScene:
    """RenderInputs with their grids read and their native objects made: what every render of them, from any
    view, re-uses."""
    inputs: scene_inputs.RenderInputs
    volumes: list                       # LoadedVolume
    errors: list = field(default_factory=list)    # volumes that could not be read, one message each
    lighting: tuple = ()                # shaded: (transfer functions, lights, ambient, Shading)
    warnings: list = field(default_factory=list)  # volumes rendered from a coarse level, one message each
    # One frame over several processes (batch.split_frame): (k, n), this render's share k of n of each streamed
    # volume's bricks (shaded, MIP) or batches (X-ray); None: all of them.
    share: tuple | None = None

    @property
    def grids(self):
        return [volume.grid for volume in self.volumes]

    @property
    def xray_grids(self):
        """X-ray's grids; a share's streams restricted to their share of the batches of stream_memory_limit's size
        (in-memory grids: share 0's, None in the others)."""
        import pcvr_native

        grids = [volume.xray_grid for volume in self.volumes]
        if self.share is None:
            return grids
        part, parts = self.share
        shared = []
        for grid in grids:
            if isinstance(grid, pcvr_native.GridStream):
                size = xray_batch_bytes(grid, self.stream_memory_limit)
                batches = _share_of(range(grid.batch_count(size)), part, parts)
                shared.append(grid.with_batches(batches, size) if batches else None)
            else:
                shared.append(grid if part == 0 else None)
        return shared

    def brick_arguments(self, grid):
        """render_shaded's and render_mip's brick_bytes and brick_share for `grid`: a stream renders in bricks of
        at most Stream Above's bytes of values; nothing for a Grid."""
        import pcvr_native

        if not isinstance(grid, pcvr_native.GridStream):
            return {}
        return {"brick_bytes": self.stream_memory_limit // 2, **({"brick_share": self.share} if self.share else {})}

    @property
    def stream_memory_limit(self):
        """A streamed volume's memory limit: bricks (shaded, MIP) of at most Stream Above's bytes of values, and
        a split frame's X-ray batches too."""
        import pcvr_native
        return 2 * (stream_threshold(self.inputs.stream_above_mib) or pcvr_native.default_memory_limit() // 4)

    @property
    def xray_attenuation(self):
        return [volume.xray_attenuation for volume in self.volumes]

    @property
    def albedo_grids(self):
        """render_shaded's albedo_grids: one (red, green, blue) or None per volume; None when no volume has them."""
        grids = [volume.albedo_grids for volume in self.volumes]
        return grids if any(grids) else None

    @property
    def density_scales(self):
        return [volume.inputs.density_scale for volume in self.volumes]

    @property
    def clip_arguments(self):
        """The native renders' clip keywords for the grids of all volumes, one entry each."""
        return clipping.native_arguments([volume.inputs.clipping for volume in self.volumes])

    def with_inputs(self, inputs):
        """The same prepared scene for `inputs` that differ from its own in their clipping only."""
        volumes = [dataclasses.replace(volume, inputs=inputs.volumes[volume.index]) for volume in self.volumes]
        return dataclasses.replace(self, inputs=inputs, volumes=volumes)

    @property
    def streamed(self):
        """How many volumes are read from their files while rendering (X-ray of big volumes)."""
        import pcvr_native
        return sum(isinstance(volume.grid, pcvr_native.GridStream) for volume in self.volumes)


# render_xray's batch size for a stream when no memory limit says (GridStream::kDefaultBatchBytes).
DEFAULT_BATCH_BYTES = 64 << 20


def xray_batch_bytes(stream, memory_limit=None):
    """The bytes of values render_xray(stream, memory_limit=...) reads a batch at a time: half the limit, or
    the default, or less where the stream asks for less (as streamed_xray.cpp chooses)."""
    size = memory_limit // 2 if memory_limit else DEFAULT_BATCH_BYTES
    return min(size, stream.batch_bytes) if stream.batch_bytes else size


def _share_of(items, part, parts):
    """Share `part` of `parts` of `items`: consecutive runs, as the native brick shares are cut."""
    items = list(items)
    return items[len(items) * part // parts:len(items) * (part + 1) // parts]


def bricks_refused(inputs):
    """Why shaded or MIP mode cannot render a streamed volume in bricks (render_shaded's GridStream), or None:
    several volumes rendered together, shadows, ambient occlusion and Color Attributes need every voxel at once."""
    if inputs.mode != 'SHADED':
        return None  # MIP renders each volume alone
    if sum(volume.has_grid for volume in inputs.volumes) > 1:
        return "several volumes shade together"
    if inputs.sheets is not None and inputs.sheets.shadows:
        return "shadows need every voxel at once"
    for volume in inputs.volumes:
        if volume.material is not None and volume.material.ambient_occlusion:
            return "ambient occlusion needs every voxel at once"
        if volume.medium is not None and volume.medium.colour_grid:
            return "a Color Attribute needs every voxel at once"
    return None


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
    if volume.value_map is not None:
        # The attribute a fluid domain's material reads, computed per voxel from the grid's values as Cycles does.
        grid = cache.grids.get(volume.filepath, volume.grid_name, read_grid)
        return pcvr_native.AttenuationMap(*volume.value_map.points()).apply(grid)
    if stream_above is not None and value_bytes(volume.filepath, volume.grid_name) > stream_above:
        try:
            return cache.grids.get(volume.filepath, volume.grid_name, stream_grid, kind="stream")
        except pcvr_native.GridError:
            pass  # a double grid, a level set: converted as a whole
    return cache.grids.get(volume.filepath, volume.grid_name, read_grid)


def _colour_grids(volume, level):
    """The (red, green, blue) Grids of a VolumeInputs' Color Attribute, placed as its grid and at its level."""
    parts = cache.grids.get(volume.filepath, volume.medium.colour_grid, read_vector_grid, kind="vector")
    if level:
        parts = [part.level(level, LEVEL_REDUCTIONS['SHADED']) for part in parts]
    return tuple(part.with_index_to_world(volume.matrix @ part.index_to_world) for part in parts)


def prepare(inputs, cancelled=lambda: False, reading=lambda name: None):
    """PreparedScene of RenderInputs. A volume that cannot be read is left out with a message in `errors`;
    `reading(name)` is told of each volume before it is read; a true `cancelled()` stops reading. Raises
    ValueError for a transfer function without a range."""
    import pcvr_native

    loaded, errors, warnings = [], [], []
    stream_above = stream_threshold(inputs.stream_above_mib)
    refused = bricks_refused(inputs) if inputs.mode in LEVEL_REDUCTIONS else None
    for index, volume in enumerate(inputs.volumes):
        if cancelled():
            break
        warnings.extend(volume.warnings)
        if not volume.has_grid:
            continue
        reading(volume.name)
        try:
            grid = _grid(volume, stream_above)
            stream, level = None, 0
            if isinstance(grid, pcvr_native.GridStream) and refused:
                # Bricks cannot serve: the finest level that fits stands in for the volume (otherwise shaded and
                # MIP render the stream at full resolution, a brick at a time).
                stream, level = grid, fitting_level(grid.value_bytes, stream_above)
                grid = stream.level(level, LEVEL_REDUCTIONS[inputs.mode])
                warnings.append(f"Volume object '{volume.name}': {stream.value_bytes / MiB:,.0f} MiB of voxels, more "
                                f"than Stream Above, and {refused}: rendered from level {level} of detail "
                                f"(1/{2 ** level} of its resolution)")
        except (OSError, ValueError, RuntimeError, MemoryError) as ex:
            errors.append(f"Volume object '{volume.name}': {ex}")
            continue
        placement = volume.placement((stream or grid).index_to_world)
        placed = [None if g is None else g.with_index_to_world(placement @ g.index_to_world) for g in (grid, stream)]
        loaded.append(LoadedVolume(index, volume, placed[0], placed[1], level))
        if volume.medium is not None and volume.medium.colour_grid:
            try:
                loaded[-1].albedo_grids = _colour_grids(volume, level)
            except (OSError, ValueError, RuntimeError, MemoryError) as ex:
                warnings.append(f"Volume object '{volume.name}': Color Attribute '{volume.medium.colour_grid}' not "
                                f"read ({ex}): the Color alone colours it")
        if inputs.xray is not None and volume.mu_water_per_cm is not None:
            _attenuate(loaded[-1], volume.mu_water_per_cm * inputs.centimetres_per_unit)
    prepared = PreparedScene(inputs, loaded, errors, warnings=warnings)
    if inputs.mode == 'SHADED' and loaded:
        prepared.lighting = _native_lighting(prepared)
    return prepared


class Preparer:
    """prepare, re-using the last PreparedScene where only the clipping changed (a crop box or clip plane dragged
    in the viewport): the cut costs nothing to prepare, while preparing again maps a volume in Hounsfield units to
    attenuation anew (0.11 s for a 256^3 CT head, against 0.23 s for its 512^2 X-ray, 2 busy cores). Call it from
    one thread."""

    def __init__(self):
        self._last = None   # (inputs without clipping, PreparedScene)

    def __call__(self, inputs):
        uncut = inputs.without_clipping()
        if self._last is not None and self._last[0] == uncut:
            return self._last[1].with_inputs(inputs)
        prepared = prepare(inputs)
        self._last = (uncut, prepared)
        return prepared


def _attenuate(volume, mu_water):
    """An X-ray of a LoadedVolume in Hounsfield units integrates mu = mu_water (1 + HU / 1000) (per world unit):
    a grid is mapped once here, for every view the prepared scene renders; a stream as it is read."""
    import pcvr_native

    volume.attenuation = pcvr_native.AttenuationMap.hounsfield(mu_water)
    if not isinstance(volume.grid, pcvr_native.GridStream):
        volume.attenuated = volume.attenuation.apply(volume.grid)


def density_range(ramp, volume):
    """The densities a LoadedVolume's (or FinishingVolume's) ramp (RampInputs) spans: (tf_min, tf_max), or its grid's."""
    return transfer_function.density_range(ramp, volume.value_range, volume.inputs.density_scale)


def control_points(ramp, volume):
    """A LoadedVolume's (or FinishingVolume's) ramp (RampInputs) as ControlPoints over its density range.
    ValueError names the volume."""
    low, high = density_range(ramp, volume)
    try:
        return transfer_function.points_over_range(ramp.positions, ramp.rgba, low, high)
    except ValueError as ex:
        raise ValueError(f"Volume object '{volume.inputs.name}': {ex}") from None


def native_transfer_function(volume):
    """pcvr_native.TransferFunction of a LoadedVolume in shaded mode."""
    import pcvr_native

    ramp = volume.inputs.ramp
    # The opacity's unit is the volume's own voxel, also where a coarser level stands in for it.
    voxel = transfer_function.smallest_voxel_spacing(volume.grid.index_to_world) / 2 ** volume.level
    if volume.inputs.medium is not None:
        density, rgba, emission = volume_material.media_transfer_function(
            volume.inputs.medium, volume.value_range, volume.inputs.density_scale, voxel, volume.inputs.medium_scale)
        return pcvr_native.TransferFunction(density, rgba, unit_distance=voxel, emission=emission)
    points = control_points(ramp, volume)
    unit_distance = voxel / ramp.opacity_scale
    return pcvr_native.TransferFunction(points.density, points.rgba, unit_distance=unit_distance,
                                        gradient=ramp.gradient, gradient_opacity=ramp.gradient_opacity)


def _native_lighting(prepared):
    """(transfer functions, lights, ambient colour, one Shading per volume) for render_shaded: the scene's lights
    and world, and each volume's material. A volume without shading shows its transfer function's colours."""
    import pcvr_native

    transfer_functions = [native_transfer_function(volume) for volume in prepared.volumes]
    shadings = []
    for volume in prepared.volumes:
        medium = volume.inputs.medium
        use_shading, ambient, diffuse, specular, shininess, anisotropy, occlusion, octaves = volume.inputs.material
        if medium is not None:
            # A Blender material is a scattering medium: scattering with its phase function, as Cycles lights it
            # (its transfer function's colour is the albedo), not Blinn-Phong on gradients.
            shadings.append(pcvr_native.Shading(model="scatter", anisotropy=medium.anisotropy, ambient_occlusion=occlusion,
                                                scattering_octaves=octaves))
            continue
        if anisotropy is not None:
            shadings.append(pcvr_native.Shading(model="scatter", anisotropy=anisotropy, lit=use_shading,
                                                ambient_occlusion=occlusion, scattering_octaves=octaves))
            continue
        shadings.append(pcvr_native.Shading(ambient=ambient, diffuse=diffuse, specular=specular,
                                            shininess=shininess, lit=use_shading, ambient_occlusion=occlusion))
    lights = []
    for spec in prepared.inputs.lights:
        # The scene's shadows (render_shaded's `shadows`) reach the lights whose Cast Shadow is on; a sun's Angle
        # softens them.
        shadow = None if spec.shadow else False
        if spec.kind == "sun":
            lights.append(pcvr_native.Light.sun(spec.vector, color=spec.color, strength=spec.strength, shadow=shadow,
                                                angle=spec.angle))
        else:
            lights.append(pcvr_native.Light.point(spec.vector, color=spec.color, strength=spec.strength, shadow=shadow))
    return transfer_functions, lights, prepared.inputs.world, shadings


def object_grid(depsgraph, obj):
    """The world-space grid of the volume object `obj`, read through the cache."""
    obj_eval = obj.evaluated_get(depsgraph)
    return load_grid(volumes.source_of(obj_eval, obj_eval.matrix_world, depsgraph))
