# SPDX-License-Identifier: GPL-3.0-or-later

"""PCVR settings: one property group per datablock (scene, view layer, volume). Defaults that pcvr_native
also has come from scene/defaults.py, and so does NATIVE_NAMES, pcvr_native's spelling of the enum items below."""

import bpy
from bpy.props import (
    BoolProperty,
    CollectionProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)

from ..scene import defaults, first_look, transfer_function

enum_modes = (
    ('XRAY', "X-Ray", "Line integral of the density along each pixel's ray"),
    ('SHADED', "Shaded",
     "Each volume's transfer function gives colour and opacity, lit by the scene's lights and world"),
    ('MIP', "Maximum Intensity",
     "The largest density along each pixel's ray, through the transfer function's colours or in grey"),
)

enum_methods = (
    ('REGULAR', "Regular",
     "Classic splatting: every voxel's footprint is rasterised at image resolution"),
    ('PCVR', "Post-Convolved",
     "Splat into a coarser subgrid, then one separable post-convolution (fast at high magnification)"),
    ('BILINEAR_SPREAD', "Bilinear Spread",
     "Spread each voxel bilinearly into the subgrid, then post-convolve (Westenberg-Roerdink)"),
)

enum_splat_kernels = (
    ('GAUSS_1_4', "Gaussian 1.4", "exp(-1.4 r\u00b2) over 2 voxels: little aliasing"),
    ('GAUSS_2_0', "Gaussian 2.0", "exp(-2 r\u00b2) over 2 voxels: sharper, more ripple"),
    ('LINEAR', "Linear", "1 - r over 1 voxel"),
    ('BOX', "Box", "Unit-volume ball: nearest neighbour, blocky"),
)

enum_post_filters = (
    ('BILINEAR', "Bilinear", "Linear interpolation of the subgrid samples"),
    ('GAUSS_1_4', "Gaussian 1.4", "exp(-1.4 t\u00b2) over 2 subgrid nodes: smoother"),
    ('GAUSS_2_0', "Gaussian 2.0", "exp(-2 t\u00b2) over 2 subgrid nodes"),
    ('CATMULL_ROM', "Catmull-Rom", "Cubic through the subgrid samples: sharp, with slight overshoot at edges"),
)

enum_passbands = (
    ('COMPENSATED', "Compensated", "A small sharpening pays back the blur of the splat kernel and the post filter: "
                                   "closest to the line integrals of the sampled volume"),
    ('PAPER', "Paper", "The paper's splat kernel and post filter as they are (softer)"),
)

enum_sheet_fills = (
    ('AUTO', "Automatic", "Sample the volume into the sheets where its footprints cover a few pixels (some of it at "
                          "stride 1), splat it elsewhere: the faster of the two, measured"),
    ('SPLAT', "Splat", "Always splat the voxels into the sheets: the kernel's own reconstruction, about 1 dB nearer "
                       "the reference ray caster where sampling is chosen"),
    ('SAMPLE', "Sample", "Always sample the volume's prefiltered lattice at the pixels that may be seen, at stride 1"),
)

enum_mip_colors = (
    ('TRANSFER_FUNCTION', "Transfer Function", "The colour of the transfer function at the largest density"),
    ('GREYSCALE', "Greyscale", "Black at the transfer function's lowest density to white at its highest"),
)


class DatablockSettings:
    """A property group stored as `pcvr` on every datablock of the type `owner`."""
    owner = None  # the bpy.types class, set by each group
    label = ""

    @classmethod
    def register(cls):
        cls.owner.pcvr = PointerProperty(
            name=f"PCVR {cls.label} Settings",
            description=f"PCVR {cls.label.lower()} settings",
            type=cls,
        )

    @classmethod
    def unregister(cls):
        del cls.owner.pcvr


def update_render_passes(self, context):
    # So that the Render Layers node of the compositor shows the passes right away.
    for view_layer in context.scene.view_layers:
        view_layer.update_render_passes()


def tag_changed(self, _context):
    """Tag the datablock as changed. Blender does not for settings that Python defines, and the rendered
    viewport hears of a change (view_update), and reads its evaluated copy, only through such a tag."""
    self.id_data.update_tag()


def update_mode(self, context):
    update_render_passes(self, context)
    tag_changed(self, context)
    # X-ray images through the Standard view transform (AgX washes them out).
    first_look.show_xray_plainly(self.id_data)


def scatters(settings):
    """Whether a volume's shaded look is a scattering medium: the Scattering model, or Source: Material."""
    return settings.shading_model == 'SCATTER' or settings.source == 'MATERIAL'


def follow_scattering(self, context):
    """Until the user sets Ambient Occlusion, it is on where the volume scatters, as Cycles shadows the world's light
    through a medium (measured against Cycles: Quick Smoke 45.5 to 62.9 dB, the CT head 39.8 to 49.7 dB,
    docs/shaded-rendering-in-blender.md), and off for Blinn-Phong with a transfer function (the presets' look, and
    six light volumes fewer per render)."""
    if not self.ambient_occlusion_set:
        self.ambient_occlusion = scatters(self)
        self.ambient_occlusion_set = False  # set by the line above's update, not by the user
    tag_changed(self, context)


def update_ambient_occlusion(self, context):
    self.ambient_occlusion_set = True
    tag_changed(self, context)


class PCVRSceneSettings(DatablockSettings, bpy.types.PropertyGroup):
    owner = bpy.types.Scene
    label = "Render"

    mode: EnumProperty(
        name="Mode",
        description="What the image shows",
        items=enum_modes,
        default='XRAY',
        update=update_mode,
    )
    method: EnumProperty(
        name="Method",
        description="Splatting algorithm",
        items=enum_methods,
        default=defaults.identifier(defaults.XRAY["method"]),
        update=tag_changed,
    )
    splat_kernel: EnumProperty(
        name="Splat Kernel",
        description="Reconstruction kernel of a voxel",
        items=enum_splat_kernels,
        default=defaults.identifier(defaults.XRAY["splat_kernel"]),
        update=tag_changed,
    )
    post_filter: EnumProperty(
        name="Post Filter",
        description="Filter that turns the subgrid into the image (X-ray)",
        items=enum_post_filters,
        default=defaults.identifier(defaults.XRAY["post_filter"]),
        update=tag_changed,
    )
    passband: EnumProperty(
        name="Passband",
        description="X-ray with PCVR or regular splatting: pay back the blur of the splat kernel and post filter",
        items=enum_passbands,
        default=defaults.identifier(defaults.XRAY["passband"]),
        update=tag_changed,
    )
    subgrid_stride: IntProperty(
        name="Subgrid Stride",
        description="Spacing of the splatting subgrid in pixels; 0 picks it from the projected voxel spacing",
        min=0, soft_max=16,
        default=defaults.XRAY["stride"],
        update=tag_changed,
    )
    sheet_post_filter: EnumProperty(
        name="Post Filter",
        description="Filter that turns each sheet's subgrid into pixels (shaded and maximum intensity)",
        items=enum_post_filters,
        default=defaults.identifier(defaults.SHEETS["post_filter"]),
        update=tag_changed,
    )
    sheet_spacing: FloatProperty(
        name="Sheet Spacing",
        description="Voxels along the view between the sheets the volume is cut into: smaller is finer and slower",
        min=0.05, soft_min=0.25, soft_max=4.0,
        default=defaults.SHEETS["sheet_spacing"],
        update=tag_changed,
    )
    samples_per_sheet: IntProperty(
        name="Samples per Sheet",
        description="Classified samples from one sheet to the next, interpolated between them: more resolve "
                    "thin features of the transfer function",
        min=1, soft_max=8,
        default=defaults.SHEETS["samples_per_sheet"],
        update=tag_changed,
    )
    sheet_fill: EnumProperty(
        name="Sheet Fill",
        description="Shaded, post-convolved: how the sheets get the volume's values",
        items=enum_sheet_fills,
        default=defaults.identifier(defaults.SHEETS["sheet_fill"]),
        update=tag_changed,
    )
    opacity_cutoff: FloatProperty(
        name="Opacity Cutoff",
        description="A pixel this opaque takes no more samples (1: never stop early)",
        min=0.5, max=1.0,
        default=defaults.SHEETS["opacity_cutoff"],
        update=tag_changed,
    )
    shadows: BoolProperty(
        name="Shadows",
        description="Shaded: the volumes attenuate the light on its way to each sample (for every light whose "
                    "Cast Shadow is on): a volume darkens what lies behind it as seen from the light",
        default=False,
        update=tag_changed,
    )
    mip_color: EnumProperty(
        name="Colors",
        description="How the largest density along a ray becomes a colour",
        items=enum_mip_colors,
        default='TRANSFER_FUNCTION',
        update=tag_changed,
    )
    stream_above: IntProperty(
        name="Stream Above",
        description="Volumes whose voxels take more than this many MiB are not read whole: X-ray reads them from "
                    "their files a part at a time while rendering, shaded and maximum intensity in bricks of at most "
                    "this many MiB composited front to back (the finest level of detail that fits where shadows, "
                    "ambient occlusion, a Color Attribute or several shaded volumes need every voxel at once; 0: "
                    "above a quarter of the memory available)",
        min=0, soft_max=65536,
        default=0,
        update=tag_changed,
    )
    xray_gain: FloatProperty(
        name="Gain",
        description="Attenuation per unit of integrated density in the Combined pass: 1 - exp(-gain * integral)",
        min=0.0, soft_max=10.0,
        default=1.0,
        update=tag_changed,
    )
    use_auto_exposure: BoolProperty(
        name="Automatic Exposure",
        description="Choose the gain from each image: its brightest percent of the volume's pixels shows 80% "
                    "grey (DRRs of any scale, for a look; the XRay pass keeps the raw integral)",
        default=False,
        update=tag_changed,
    )


class PCVRViewLayerSettings(DatablockSettings, bpy.types.PropertyGroup):
    owner = bpy.types.ViewLayer
    label = "View Layer"

    use_pass_xray: BoolProperty(
        name="X-Ray",
        description="Raw line integral of the density, one channel, for the compositor",
        default=False,
        update=update_render_passes,
    )


def ramp_texture_property(name, description):
    """A pointer to a Texture whose colour ramp the volume's settings use (a Texture is an ID: see
    scene/transfer_function.py)."""
    return PointerProperty(name=name, description=description, type=bpy.types.Texture,
                           poll=lambda _self, texture: texture.use_color_ramp, update=tag_changed)


class PCVRClipPlane(bpy.types.PropertyGroup):
    """One clip plane of a volume: an object whose local +Z side is kept."""
    object: PointerProperty(
        name="Object",
        description="Object (an empty) whose local +Z side is kept: the plane through its origin, normal to its "
                    "Z axis",
        type=bpy.types.Object,
        update=tag_changed,
    )
    enabled: BoolProperty(
        name="Enabled",
        description="Cut the volume at this plane",
        default=True,
        update=tag_changed,
    )


class PCVRVolumeSettings(DatablockSettings, bpy.types.PropertyGroup):
    owner = bpy.types.Volume
    label = "Volume"

    grid: StringProperty(
        name="Grid",
        description="Name of the grid to render; empty uses 'density', or else the first float grid",
        default="",
        update=tag_changed,
    )
    density_scale: FloatProperty(
        name="Density Scale",
        description="Multiplier of the grid values",
        min=0.0, soft_max=10.0,
        default=1.0,
        update=tag_changed,
    )
    # What shaded mode renders: the transfer function, or the object's material (scene/volume_material.py).
    source: EnumProperty(
        name="Source",
        description="What gives the volume its colour, opacity and light in shaded mode",
        items=[('TRANSFER_FUNCTION', "Transfer Function", "The transfer function's colour ramp over the grid"),
               ('MATERIAL', "Material", "The object's material: its Principled Volume (density, colour, absorption, "
                "emission, blackbody fire from the temperature grid), each grid it names rendered together")],
        default='TRANSFER_FUNCTION',
        update=follow_scattering,
    )
    # What an X-ray integrates (X-ray mode and the XRay pass).
    xray_values: EnumProperty(
        name="X-Ray Values",
        description="What the grid's values are to an X-ray",
        items=[('DENSITY', "Density", "Integrate the values as they are (times the density scale)"),
               ('HOUNSFIELD', "Hounsfield Units",
                "A CT in Hounsfield units: integrate the linear attenuation mu = mu_water (1 + HU / 1000), never "
                "below 0, as DRR tools do")],
        default='DENSITY',
        update=tag_changed,
    )
    mu_water: FloatProperty(
        name="Water Attenuation",
        description="Linear attenuation coefficient of water per centimetre (0.193 near 70 keV), converted to the "
                    "scene's length unit (Scene > Units > Unit Scale)",
        min=1e-6, soft_max=1.0, precision=4,
        default=0.193,
        update=tag_changed,
    )

    # Clipping (every mode); see scene/clipping.py.
    use_crop: BoolProperty(
        name="Crop",
        description="Keep only the part of the volume inside the crop object's box",
        default=False,
        update=tag_changed,
    )
    crop_object: PointerProperty(
        name="Crop Object",
        description="Object whose local box from -1 to 1 on each axis is kept (Blender's default cube; an empty "
                    "displayed as a cube draws it)",
        type=bpy.types.Object,
        update=tag_changed,
    )
    clip_planes: CollectionProperty(
        name="Clip Planes",
        description="Objects whose local +Z side is kept: the volume is cut at each one's XY plane",
        type=PCVRClipPlane,
    )
    clip_plane_index: IntProperty(
        name="Active Clip Plane",
        description="The clip plane chosen in the list",
        default=0,
    )

    # The transfer function (shaded and maximum intensity modes); see scene/transfer_function.py.
    transfer_function: ramp_texture_property(
        name="Transfer Function",
        description="Texture whose colour ramp gives colour (RGB) and opacity per voxel (alpha) over the range",
    )
    use_grid_range: BoolProperty(
        name="Range from Grid",
        description="Spread the colour ramp over the grid's values (times the density scale), from the lowest "
                    "to the highest, at every render",
        default=True,
        update=tag_changed,
    )
    tf_min: FloatProperty(
        name="Min",
        description="Density at the left end of the colour ramp (the grid's units: e.g. Hounsfield for CT)",
        default=0.0,
        update=tag_changed,
    )
    tf_max: FloatProperty(
        name="Max",
        description="Density at the right end of the colour ramp",
        default=1.0,
        update=tag_changed,
    )
    opacity_scale: FloatProperty(
        name="Opacity Scale",
        description="Multiplier of the extinction: 2 makes a voxel as opaque as two were",
        min=0.001, soft_max=10.0,
        default=1.0,
        update=tag_changed,
    )
    # Gradient opacity (shaded mode): the opacity times a ramp's alpha over |gradient|; see scene/transfer_function.py.
    use_gradient_opacity: BoolProperty(
        name="Gradient Opacity",
        description="Scale the opacity by a function of how fast the density changes: boundaries stay, uniform "
                    "regions fade (VTK's and 3D Slicer's gradient opacity)",
        default=False,
        update=tag_changed,
    )
    gradient_opacity: ramp_texture_property(
        name="Gradient Opacity",
        description="Texture whose colour ramp's alpha is the opacity factor over gradient magnitudes 0 to Max "
                    "Gradient",
    )
    gradient_max: FloatProperty(
        name="Max Gradient",
        description="Gradient magnitude at the right end of the gradient-opacity ramp, in density units (times the "
                    "density scale) per world unit; the ramp's last factor holds beyond",
        min=1e-9, soft_max=1000.0,
        default=1.0,
        update=tag_changed,
    )
    # The material of shaded mode (Blinn-Phong, as VTK and 3D Slicer light volumes).
    use_shading: BoolProperty(
        name="Shading",
        description="Light the volume with the scene's lights and world; off: the transfer function's colours "
                    "as they are (3D Slicer's presets without shading)",
        default=True,
        update=tag_changed,
    )
    ambient: FloatProperty(
        name="Ambient", description="Share of the world colour a sample reflects",
        min=0.0, soft_max=1.0, default=defaults.MATERIAL["ambient"],
        update=tag_changed,
    )
    diffuse: FloatProperty(
        name="Diffuse", description="Share of the lights a sample reflects diffusely",
        min=0.0, soft_max=1.0, default=defaults.MATERIAL["diffuse"],
        update=tag_changed,
    )
    specular: FloatProperty(
        name="Specular", description="Strength of the white highlights",
        min=0.0, soft_max=1.0, default=defaults.MATERIAL["specular"],
        update=tag_changed,
    )
    shininess: FloatProperty(
        name="Shininess", description="Exponent of the highlights: higher is smaller and sharper",
        min=0.0, soft_max=100.0, default=defaults.MATERIAL["shininess"],
        update=tag_changed,
    )
    shading_model: EnumProperty(
        name="Model",
        description="How a sample reflects the lights",
        items=[('BLINN_PHONG', "Blinn-Phong", "Surfaces lit along the density's gradient, with highlights (VTK, "
                                              "3D Slicer)"),
               ('SCATTER', "Scattering", "A medium that scatters the lights once, with a Henyey-Greenstein phase "
                                         "function, its colour the albedo (Cycles' Principled Volume)")],
        default='BLINN_PHONG',
        update=follow_scattering,
    )
    anisotropy: FloatProperty(
        name="Anisotropy",
        description="Direction of scattering: above 0 mostly forwards (bright looking into the light), below 0 "
                    "mostly back",
        min=-0.99, max=0.99, default=0.0,
        update=tag_changed,
    )
    scattering_octaves: IntProperty(
        name="Scattering Octaves",
        description="Light scattered more than once (Scattering model, and Source: Material): octaves of the lights' "
                    "shadows at lower extinction add the light a dense cloud diffuses into its shade, as Cycles' "
                    "volume bounces do; needs Shadows (and Ambient Occlusion for the world's light). 0: from the "
                    "scene's Light Paths, as Cycles renders it (0 Volume Bounces, Blender's default: single "
                    "scattering; each bounce one octave more, up to 6). 1: single scattering only",
        min=0, max=16, default=0,
        update=tag_changed,
    )
    ambient_occlusion: BoolProperty(
        name="Ambient Occlusion",
        description="Shadow the world's ambient light through the volumes, as Cycles does: each sample gets the mean "
                    "of the light arriving from six directions (costs six light volumes per render). Until set, on "
                    "where the volume scatters (Scattering model, Source: Material) and off for Blinn-Phong",
        default=False,
        update=update_ambient_occlusion,
    )
    ambient_occlusion_set: BoolProperty(
        name="Ambient Occlusion Set",
        description="Ambient Occlusion was set (by the user, a preset or a script): changing Source or Model leaves it",
        default=False,
        options={'HIDDEN'},
    )

    @property
    def ramp(self):
        """The ColorRamp of the transfer function, or None (the default ramp applies)."""
        texture = self.transfer_function
        return texture.color_ramp if texture is not None and texture.use_color_ramp else None

    @property
    def gradient_ramp(self):
        """The ColorRamp of the gradient opacity, or None (DEFAULT_GRADIENT_RAMP applies)."""
        texture = self.gradient_opacity
        return texture.color_ramp if texture is not None and texture.use_color_ramp else None

    def _ensure_texture(self, name, label, elements):
        """The texture that property `name` points to, a new one holding `elements` when there is none."""
        if getattr(self, name) is None:
            setattr(self, name, transfer_function.new_ramp_texture(bpy.data.textures, f"{self.id_data.name} {label}",
                                                                    elements))
        return getattr(self, name)

    def ensure_transfer_function(self):
        """The transfer function's texture, a new one holding the default ramp when the volume has none."""
        return self._ensure_texture("transfer_function", "Transfer Function", transfer_function.DEFAULT_RAMP)

    def ensure_gradient_opacity(self):
        """The gradient opacity's texture, a new one holding the default ramp when the volume has none."""
        return self._ensure_texture("gradient_opacity", "Gradient Opacity", transfer_function.DEFAULT_GRADIENT_RAMP)

    def set_gradient_opacity(self, gradient_max, elements, interpolation='LINEAR'):
        """The gradient-opacity ramp `elements`, (position, rgba) pairs, over magnitudes 0 to gradient_max. What
        presets call (use_gradient_opacity is theirs to set)."""
        transfer_function.set_ramp(self.ensure_gradient_opacity().color_ramp, elements, interpolation)
        self.gradient_max = gradient_max

    def set_transfer_function(self, tf_min, tf_max, elements, interpolation='LINEAR', color_mode='RGB'):
        """The ramp `elements`, (position, rgba) pairs, over densities tf_min to tf_max (range no longer
        from the grid). What presets call."""
        transfer_function.set_ramp(self.ensure_transfer_function().color_ramp, elements, interpolation, color_mode)
        self.use_grid_range = False
        self.tf_min, self.tf_max = tf_min, tf_max

    def set_material(self, ambient, diffuse, specular, shininess):
        self.ambient, self.diffuse, self.specular, self.shininess = ambient, diffuse, specular, shininess

    def apply_slicer_preset(self, scalar_opacity, color_transfer, shade, ambient, diffuse, specular,
                            specular_power, gradient_opacity=None):
        """A 3D Slicer volume-rendering preset, its numbers as presets.xml has them (see
        transfer_function.slicer_ramp and slicer_gradient_ramp); the opacity scale returns to 1."""
        tf_min, tf_max, elements = transfer_function.slicer_ramp(scalar_opacity, color_transfer)
        gradient = None if gradient_opacity is None else transfer_function.slicer_gradient_ramp(gradient_opacity)
        self.set_transfer_function(tf_min, tf_max, elements)
        if gradient is not None:
            self.set_gradient_opacity(*gradient)
        self.use_gradient_opacity = gradient is not None
        self.set_material(ambient, diffuse, specular, specular_power)
        self.use_shading = shade
        self.opacity_scale = 1.0

    def apply_preset(self, name):
        """The transfer-function preset called `name` (as the preset menu lists it, e.g. "CT Bone"), shipped
        or saved by the user. Raises KeyError naming the presets there are."""
        from . import presets  # which writes settings as this module types them
        presets.apply(self.id_data, name)


classes = (
    PCVRSceneSettings,
    PCVRViewLayerSettings,
    PCVRClipPlane,
    PCVRVolumeSettings,
)


register, unregister = bpy.utils.register_classes_factory(classes)
