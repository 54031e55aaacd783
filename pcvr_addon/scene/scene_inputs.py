# SPDX-License-Identifier: GPL-3.0-or-later

"""What a render reads from Blender, read at once into plain values that compare by content.

A render then runs without touching Blender data (the viewport renders on a worker thread, where bpy must not
be used), and two readings compare equal exactly when they would give the same image, which is how the
viewport tells a change that needs a new render from one that needs none (selecting an object, or moving a
light in X-ray mode). Each mode reads only what it uses:

| type          | what                                                   | read for               |
|---------------|--------------------------------------------------------|------------------------|
| RenderInputs  | what the native render call depends on                 | every mode             |
| VolumeInputs  | one volume instance: its grid's source, placement and clipping | every mode     |
| RampInputs    | a transfer function: the ramp's points and its range   | shaded (render), MIP (display) |
| XRaySettings  | render_xray's options                                  | X-ray, and the XRay pass |
| SheetSettings | render_shaded's and render_mip's options               | shaded and MIP         |
| DisplayInputs | what turns the native result into the Combined pass    | every mode             |

Call `read` on Blender's main thread (or in RenderEngine.render).
"""

import dataclasses
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from . import lighting, transfer_function, volume_material, volumes
from .clipping import ClipError, Clipping, volume_clipping
from .defaults import NATIVE_NAMES
from .typed import as_typed


class Material(NamedTuple):
    """A volume's shading settings as the native Shading takes them (anisotropy None: Blinn-Phong)."""
    use_shading: bool
    ambient: float
    diffuse: float
    specular: float
    shininess: float
    anisotropy: float | None
    ambient_occlusion: bool
    scattering_octaves: int


@dataclass(frozen=True)
class RampInputs:
    positions: tuple     # ramp positions in 0..1, increasing
    rgba: tuple          # one (r, g, b, a) per position
    use_grid_range: bool
    tf_min: float
    tf_max: float
    opacity_scale: float
    gradient: tuple = ()          # gradient opacity (shaded mode): increasing |gradient| per world unit, or none
    gradient_opacity: tuple = ()  # the opacity factor at each


@dataclass(frozen=True)
class VolumeInputs:
    name: str                # object name, for messages
    filepath: str            # the unchanged file the grid comes from, or "" (then `grid` holds it)
    grid_name: str | None
    object_to_world: tuple   # 4 rows of 4
    density_scale: float
    error: str = ""          # why the volume cannot be read, "" when it can
    ramp: RampInputs | None = None     # shaded mode
    material: Material | None = None   # shaded mode: see material()
    mu_water_per_cm: float | None = None  # X-ray of a CT in Hounsfield units: water's attenuation; None: densities
    clipping: Clipping = Clipping()  # what of it is kept (crop box, clip planes)
    # Shaded mode with volume.pcvr.source 'MATERIAL': the part of the material this grid renders (None: the
    # transfer function), and what of the material was not followed.
    medium: volume_material.GridMedium | None = None
    # The medium's units of length per world unit: Render > Space Object, the object's (along the view); World, 1.
    medium_scale: float = 1.0
    warnings: tuple = ()
    # A procedural volume's grid, exported from Blender while reading (compares by identity: a new export is
    # a change).
    grid: object = None
    # Where the file's index space lies in object space, instead of where its transform says (a fluid cache's
    # cells on its domain); None: the file's transform.
    index_to_object: tuple | None = None
    # The attribute the grid's values stand for, mapped per voxel as Cycles does (a fluid domain's temperature from
    # its flame grid): a fluid_domain.ValueMap, or None.
    value_map: object = None

    @property
    def matrix(self):
        return np.array(self.object_to_world, dtype=np.float64)

    @property
    def has_grid(self):
        """Whether there is a grid to read (a fluid domain without its cache frame has only a warning)."""
        return bool(self.filepath or self.grid is not None or self.error)

    def placement(self, file_index_to_world):
        """The matrix taking its grid's index-to-world matrix to world space (volumes.placement)."""
        return volumes.placement(self.matrix, self.index_to_object, file_index_to_world)


@dataclass(frozen=True)
class XRaySettings:
    """render_xray's keyword arguments."""
    method: str
    splat_kernel: str
    post_filter: str
    stride: int
    passband: str


@dataclass(frozen=True)
class SheetSettings:
    """render_shaded's and render_mip's keyword arguments (render_mip takes the first five)."""
    method: str
    splat_kernel: str
    post_filter: str
    stride: int
    sheet_spacing: float
    samples_per_sheet: int
    opacity_cutoff: float
    shadows: bool = False  # shaded only: the lights' transmittance through the volumes
    sheet_fill: str = "auto"  # shaded only: splat or sample the sheets (pcvr)

    def mip_arguments(self):
        return {name: getattr(self, name) for name in ("method", "splat_kernel", "post_filter", "stride",
                                                        "sheet_spacing")}


@dataclass(frozen=True)
class RenderInputs:
    mode: str                          # 'XRAY', 'SHADED' or 'MIP'
    volumes: tuple                     # VolumeInputs
    threads: int
    xray: XRaySettings | None = None   # X-ray mode, or another mode with the XRay pass
    sheets: SheetSettings | None = None
    lights: tuple = ()                 # shaded mode: lighting.LightSpec
    world: tuple = (0.0, 0.0, 0.0)     # shaded mode: the ambient light
    with_depth: bool = False           # shaded mode with the Depth pass
    # Volumes of more MiB than this are streamed from their files (0: above a quarter of the memory
    # available; None: never): X-ray reads them a part at a time, shaded and MIP in bricks (or a coarser level
    # where bricks cannot serve: render.prepared_scene.bricks_refused).
    stream_above_mib: int | None = None
    centimetres_per_unit: float = 100.0  # the scene's length unit (attenuation is per unit length)

    def without_clipping(self):
        """The same inputs with no volume cut: what prepare_scene.prepare depends on."""
        volumes = tuple(dataclasses.replace(volume, clipping=Clipping()) for volume in self.volumes)
        return dataclasses.replace(self, volumes=volumes)

    def with_sheet_spacing(self, factor):
        """The same inputs with `factor` times the sheet spacing (a coarser, faster shaded or MIP image)."""
        if self.sheets is None or factor == 1:
            return self
        sheets = dataclasses.replace(self.sheets, sheet_spacing=self.sheets.sheet_spacing * factor)
        return dataclasses.replace(self, sheets=sheets)


@dataclass(frozen=True)
class DisplayInputs:
    mode: str
    film_transparent: bool
    world: tuple = (0.0, 0.0, 0.0)   # shaded and MIP: the background
    xray_gain: float = 1.0
    auto_exposure: bool = False
    mip_color: str = 'TRANSFER_FUNCTION'
    ramps: tuple = ()                # MIP: a RampInputs per volume of RenderInputs.volumes, in that order


def _matrix(matrix):
    return tuple(tuple(float(value) for value in row) for row in np.asarray(matrix, dtype=np.float64))


def ramp_inputs(settings):
    """RampInputs of a volume's PCVR settings."""
    positions, rgba = transfer_function.ramp_points(settings.ramp)
    return RampInputs(
        positions=tuple(float(p) for p in positions),
        rgba=tuple(tuple(float(c) for c in colour) for colour in rgba),
        use_grid_range=settings.use_grid_range,
        tf_min=settings.tf_min,
        tf_max=settings.tf_max,
        opacity_scale=settings.opacity_scale,
        **gradient_opacity_inputs(settings),
    )


def gradient_opacity_inputs(settings):
    """RampInputs' gradient and gradient_opacity of a volume's PCVR settings (none when not used)."""
    if not settings.use_gradient_opacity:
        return {}
    positions, rgba = transfer_function.ramp_points(settings.gradient_ramp, transfer_function.DEFAULT_GRADIENT_RAMP)
    gradient, factors = transfer_function.gradient_points(positions, rgba, settings.gradient_max)
    return {"gradient": tuple(map(float, gradient)), "gradient_opacity": tuple(map(float, factors))}


# The most octaves Light Paths give: against the path tracer (docs/how-it-works.md), 8 octaves instead of 6 gained
# at most 0.4 dB on clouds of optical depth 1.4 to 56 across (ambient occlusion on; off, they lost up to 1.9 dB on
# the thin ones). Against Cycles, Quick Smoke at 1 volume bounce matched 2 octaves best (56.5 dB); at 2 bounces
# 3 octaves measured 54.4 dB, 2 the best at 58.4 (docs/shaded-rendering-in-blender.md).
MOST_SCENE_OCTAVES = 6


def light_paths_octaves(scene):
    """The scattering octaves that render `scene` as Cycles would: one (single scattering) at Cycles' default of 0
    Volume Bounces, each bounce one octave more, up to MOST_SCENE_OCTAVES; Cycles' Total bounces cap its volume
    bounces. A Blender without Cycles' settings renders at their default, 0 bounces."""
    cycles = getattr(scene, "cycles", None)
    bounces = min(getattr(cycles, "volume_bounces", 0), getattr(cycles, "max_bounces", 0))
    return min(1 + bounces, MOST_SCENE_OCTAVES)


def material(settings, scene_octaves=1):
    """A volume's Material, anisotropy None for Blinn-Phong (a number: scattering). Scattering Octaves 0 takes
    `scene_octaves` (light_paths_octaves)."""
    anisotropy = float(settings.anisotropy) if settings.shading_model == 'SCATTER' else None
    return Material(settings.use_shading, *(as_typed(getattr(settings, name))
                                            for name in ("ambient", "diffuse", "specular", "shininess")), anisotropy,
                    bool(settings.ambient_occlusion), int(settings.scattering_octaves) or scene_octaves)


def object_units_per_world(object_to_world, direction=None):
    """Units of the object's own space per world unit along the world `direction` (the view's), or, without one,
    of its mean scale (the cube root of its volume's): what a material's density per object unit (Render > Space:
    Object) is per world unit. The same along every direction for a uniform scale."""
    linear = np.asarray(object_to_world, dtype=np.float64)[:3, :3]
    with np.errstate(all="ignore"):
        if direction is None:
            scale = abs(np.linalg.det(linear)) ** (-1.0 / 3.0)
        else:
            along = np.asarray(direction, dtype=np.float64)
            scale = np.linalg.norm(np.linalg.solve(linear, along / np.linalg.norm(along)))
    return float(scale) if np.isfinite(scale) and scale > 0 else 1.0


def view_direction(scene, view=None):
    """The world direction a render looks along: its view's (a CameraView), else the scene camera's; None
    without either."""
    if view is not None:
        return -np.asarray(view.world_to_camera, dtype=np.float64)[2, :3]  # the camera looks down its -Z
    if scene.camera is not None:
        return -np.asarray(scene.camera.matrix_world, dtype=np.float64)[:3, 2]
    return None


def material_volume_inputs(source, mode, export_grid, direction=None, scene_octaves=1):
    """The VolumeInputs of a VolumeSource: one per grid its material names that the volume has (shaded mode with
    the source 'MATERIAL'), else one rendered with the transfer function. The first carries the warnings.
    `direction`: the view's, in world space (see object_units_per_world)."""
    if mode != 'SHADED' or source.settings.source != 'MATERIAL' or not source.has_grids:
        return (volume_inputs(source, mode, export_grid, scene_octaves),)
    media = volume_material.read(source.material)
    present = source.grid_names
    parts = [medium for medium in media.grids if source.attribute(medium) in present]
    warnings = source.warnings + tuple(f"Volume object '{source.name}': {w}" for w in media.warnings)
    if not source.filepath and any(medium.colour_grid for medium in parts):
        warnings += (f"Volume object '{source.name}': the Color Attribute of a volume made by modifiers is not read: "
                     "the Color alone colours it",)
    parts = [source.part(_with_colour_grid(medium, source, present)) for medium in parts]
    if media.grids and not parts:
        warnings += (f"Volume object '{source.name}': its material names no grid the volume has "
                     f"({', '.join(sorted(present))}): rendered with the transfer function",)
    if not parts:
        return (dataclasses.replace(volume_inputs(source, mode, export_grid, scene_octaves), warnings=warnings),)
    scale = object_units_per_world(source.object_to_world, direction) if source.render_space == 'OBJECT' else 1.0
    return tuple(dataclasses.replace(volume_inputs(part, mode, export_grid, scene_octaves), medium=medium,
                                     medium_scale=scale, warnings=(warnings if index == 0 else ()) + part.warnings)
                 for index, (part, medium) in enumerate(parts))


def _with_colour_grid(medium, source, present):
    """A GridMedium whose Color Attribute names a vector grid of the volume's file; one naming no grid it has
    loses it, as Cycles leaves the Color alone when the attribute is missing."""
    if medium.colour_grid is None or source.volume is None:
        return medium
    grid = source.volume.grids.get(medium.colour_grid) if medium.colour_grid in present else None
    if grid is None or grid.data_type not in {'VECTOR_FLOAT', 'VECTOR_DOUBLE'} or not source.filepath:
        return dataclasses.replace(medium, colour_grid=None)
    return medium


def volume_inputs(source, mode, export_grid, scene_octaves):
    """VolumeInputs of a VolumeSource. `export_grid(source)` returns the grid of a procedural volume;
    `scene_octaves`: see material()."""
    settings = source.settings
    grid, error, clipped = None, source.error, Clipping()
    try:
        clipped = volume_clipping(settings)
    except ClipError as ex:
        error = error or str(ex)
    if not source.filepath and not error and source.volume is not None:
        try:
            grid = export_grid(source)
        except (OSError, ValueError, RuntimeError, MemoryError) as ex:
            error = str(ex)
    return VolumeInputs(
        name=source.name,
        filepath=source.filepath,
        grid_name=source.grid_name,
        object_to_world=_matrix(source.object_to_world),
        density_scale=source.density_scale,
        error=error,
        ramp=ramp_inputs(settings) if mode == 'SHADED' else None,
        material=material(settings, scene_octaves) if mode == 'SHADED' else None,
        mu_water_per_cm=settings.mu_water if settings.xray_values == 'HOUNSFIELD' else None,
        clipping=clipped,
        grid=grid,
        index_to_object=source.index_to_object,
        value_map=source.value_map,
        warnings=source.warnings,
    )


def _splatting(settings, post_filter):
    """The options render_xray, render_shaded and render_mip share."""
    return dict(method=NATIVE_NAMES[settings.method], splat_kernel=NATIVE_NAMES[settings.splat_kernel],
                post_filter=NATIVE_NAMES[post_filter], stride=settings.subgrid_stride)


def xray_settings(settings):
    return XRaySettings(**_splatting(settings, settings.post_filter), passband=NATIVE_NAMES[settings.passband])


def sheet_settings(settings):
    return SheetSettings(**_splatting(settings, settings.sheet_post_filter),
                         sheet_spacing=as_typed(settings.sheet_spacing),
                         samples_per_sheet=settings.samples_per_sheet,
                         opacity_cutoff=as_typed(settings.opacity_cutoff),
                         shadows=settings.shadows,
                         # Other methods only splat.
                         sheet_fill=NATIVE_NAMES[settings.sheet_fill] if settings.method == 'PCVR' else "auto")


def read(depsgraph, export_grid, view=None, in_viewport=False, space=None):
    """(RenderInputs, DisplayInputs) of the evaluated depsgraph: the volumes that may reach `view` (None:
    all), visible in renders, or `in_viewport` in the 3D viewport (`space`: its SpaceView3D). The passes
    beyond Combined (Depth, XRay) are read for renders only."""
    scene = depsgraph.scene
    settings = scene.pcvr
    mode = settings.mode
    sources = list(volumes.in_view(depsgraph, view, in_viewport, space))
    direction = view_direction(scene, view)
    octaves = light_paths_octaves(scene)
    volume_list = tuple(part for source in sources
                        for part in material_volume_inputs(source, mode, export_grid, direction, octaves))
    with_xray_pass = not in_viewport and depsgraph.view_layer.pcvr.use_pass_xray
    world = lighting.world_colour(scene.world)
    shaded = mode == 'SHADED'
    inputs = RenderInputs(
        mode=mode,
        volumes=volume_list,
        threads=scene.render.threads,
        xray=xray_settings(settings) if mode == 'XRAY' or with_xray_pass else None,
        sheets=sheet_settings(settings) if mode != 'XRAY' else None,
        lights=tuple(lighting.scene_lights(depsgraph)) if shaded else (),
        world=world if shaded else (0.0, 0.0, 0.0),
        with_depth=shaded and not in_viewport and depsgraph.view_layer.use_pass_z,
        stream_above_mib=settings.stream_above,
        centimetres_per_unit=100.0 * scene.unit_settings.scale_length,
    )
    display = DisplayInputs(
        mode=mode,
        film_transparent=scene.render.film_transparent,
        world=world if mode != 'XRAY' else (0.0, 0.0, 0.0),
        xray_gain=settings.xray_gain if mode == 'XRAY' else 1.0,
        auto_exposure=mode == 'XRAY' and settings.use_auto_exposure,
        mip_color=settings.mip_color if mode == 'MIP' else 'TRANSFER_FUNCTION',
        ramps=tuple(ramp_inputs(source.settings) for source in sources) if mode == 'MIP' else (),
    )
    return inputs, display
