# SPDX-License-Identifier: GPL-3.0-or-later

"""PCVR settings: one property group per datablock (scene, view layer, volume)."""

import bpy
from bpy.props import (
    BoolProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)

# How pcvr_native and the command line spell the enum items below.
NATIVE_NAMES = {
    'REGULAR': "regular",
    'PCVR': "pcvr",
    'BILINEAR_SPREAD': "bilinear_spread",
    'GAUSS_1_4': "gauss1.4",
    'GAUSS_2_0': "gauss2.0",
    'LINEAR': "linear",
    'BOX': "box",
    'BILINEAR': "bilinear",
}

enum_modes = (
    ('XRAY', "X-Ray", "Line integral of the density along each pixel's ray"),
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


class PCVRSceneSettings(DatablockSettings, bpy.types.PropertyGroup):
    owner = bpy.types.Scene
    label = "Render"

    mode: EnumProperty(
        name="Mode",
        description="What the image shows",
        items=enum_modes,
        default='XRAY',
    )
    method: EnumProperty(
        name="Method",
        description="Splatting algorithm",
        items=enum_methods,
        default='PCVR',
    )
    splat_kernel: EnumProperty(
        name="Splat Kernel",
        description="Reconstruction kernel of a voxel",
        items=enum_splat_kernels,
        default='GAUSS_1_4',
    )
    post_filter: EnumProperty(
        name="Post Filter",
        description="Filter that turns the subgrid into the image",
        items=enum_post_filters,
        default='BILINEAR',
    )
    subgrid_stride: IntProperty(
        name="Subgrid Stride",
        description="Spacing of the splatting subgrid in pixels; 0 picks it from the projected voxel spacing",
        min=0, soft_max=16,
        default=0,
    )
    xray_gain: FloatProperty(
        name="Gain",
        description="Attenuation per unit of integrated density in the Combined pass: 1 - exp(-gain * integral)",
        min=0.0, soft_max=10.0,
        default=1.0,
    )


def update_render_passes(self, context):
    # So that the Render Layers node of the compositor shows the pass right away.
    context.view_layer.update_render_passes()


class PCVRViewLayerSettings(DatablockSettings, bpy.types.PropertyGroup):
    owner = bpy.types.ViewLayer
    label = "View Layer"

    use_pass_xray: BoolProperty(
        name="X-Ray",
        description="Raw line integral of the density, one channel, for the compositor",
        default=False,
        update=update_render_passes,
    )


class PCVRVolumeSettings(DatablockSettings, bpy.types.PropertyGroup):
    owner = bpy.types.Volume
    label = "Volume"

    grid: StringProperty(
        name="Grid",
        description="Name of the grid to render; empty uses 'density', or else the first float grid",
        default="",
    )
    density_scale: FloatProperty(
        name="Density Scale",
        description="Multiplier of the grid values",
        min=0.0, soft_max=10.0,
        default=1.0,
    )


classes = (
    PCVRSceneSettings,
    PCVRViewLayerSettings,
    PCVRVolumeSettings,
)


register, unregister = bpy.utils.register_classes_factory(classes)
