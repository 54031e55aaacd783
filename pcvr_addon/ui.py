# SPDX-License-Identifier: GPL-3.0-or-later

"""Panels of the PCVR settings, and the built-in panels PCVR shares."""

import bpy
from bpy.types import Panel

from . import engine


def property_split(layout):
    """`layout` in the property-split style of Blender's own render panels."""
    layout.use_property_split = True
    layout.use_property_decorate = False
    return layout


class PCVRButtonsPanel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    COMPAT_ENGINES = {'PCVR'}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES


class PCVR_RENDER_PT_xray(PCVRButtonsPanel, Panel):
    bl_label = "X-Ray"

    def draw(self, context):
        layout = property_split(self.layout)
        settings = context.scene.pcvr
        layout.prop(settings, "mode")
        layout.prop(settings, "xray_gain")


class PCVR_RENDER_PT_splatting(PCVRButtonsPanel, Panel):
    bl_label = "Splatting"

    def draw(self, context):
        layout = property_split(self.layout)
        settings = context.scene.pcvr
        col = layout.column()
        col.prop(settings, "method")
        # Only the settings the chosen method uses: bilinear spreading has no splat kernel, and
        # regular splatting has no subgrid.
        if settings.method != 'BILINEAR_SPREAD':
            col.prop(settings, "splat_kernel")
        if settings.method != 'REGULAR':
            col.prop(settings, "post_filter")
            col.prop(settings, "subgrid_stride", text="Stride")

        draw_sampling_estimate(layout.column(align=True), context)


def draw_sampling_estimate(layout, context):
    """The magnification (and stride) the volumes in view get, as far as known without reading files."""
    settings = context.scene.pcvr
    try:
        estimate = engine.sampling_estimate(context.evaluated_depsgraph_get(), settings)
    except ImportError:
        layout.label(text="The pcvr_native module is missing", icon='ERROR')
        return
    if estimate is None:
        layout.label(text="No scene camera", icon='INFO')
        return

    magnification, strides, unread = estimate
    if magnification is not None:
        low, high = magnification
        text = f"{low:.2f} px/voxel" if high - low < 0.005 else f"{low:.2f} - {high:.2f} px/voxel"
        if settings.method != 'REGULAR':
            text += ", stride " + ", ".join(str(stride) for stride in strides)
        layout.label(text=text, icon='INFO')
    if unread:
        layout.label(text=f"Render to measure {unread} volume(s) not read yet", icon='INFO')
    elif magnification is None:
        layout.label(text="No volume in view", icon='INFO')


class PCVR_RENDER_PT_film(PCVRButtonsPanel, Panel):
    bl_label = "Film"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = property_split(self.layout)
        layout.prop(context.scene.render, "film_transparent", text="Transparent")


class PCVR_RENDER_PT_passes(PCVRButtonsPanel, Panel):
    bl_label = "Passes"
    bl_context = "view_layer"

    def draw(self, context):
        layout = property_split(self.layout)
        col = layout.column(heading="Include", align=True)
        col.prop(context.view_layer.pcvr, "use_pass_xray")


class PCVR_DATA_PT_volume(PCVRButtonsPanel, Panel):
    bl_label = "PCVR"
    bl_context = "data"

    @classmethod
    def poll(cls, context):
        return context.volume and super().poll(context)

    def draw(self, context):
        layout = property_split(self.layout)
        volume = context.volume
        settings = volume.pcvr
        layout.prop_search(settings, "grid", volume, "grids", icon='VOLUME_DATA')
        layout.prop(settings, "density_scale")
        layout.operator("pcvr.frame_volume", icon='CAMERA_DATA')


def get_panels():
    """The built-in panels that PCVR shares with Blender's own engines, less those whose settings PCVR
    ignores (materials, world, lights, light probes, Freestyle, Grease Pencil, Simplify, stereoscopy,
    EEVEE's volume settings)."""
    exclude_contexts = {'material', 'world'}
    exclude_prefixes = (
        'DATA_PT_camera_stereoscopy',
        'DATA_PT_context_lightprobe',
        'DATA_PT_light',
        'DATA_PT_preview',
        'DATA_PT_spot',
        'DATA_PT_volume_render',
        'NODE_DATA_PT_light',
        'OBJECT_PT_shading',
        'RENDER_PT_freestyle',
        'RENDER_PT_gpencil',
        'RENDER_PT_grease_pencil',
        'RENDER_PT_output_views',
        'RENDER_PT_simplify',
        'RENDER_PT_stereoscopy',
        'VIEWLAYER_PT_freestyle',
    )
    return [
        panel for panel in bpy.types.Panel.__subclasses__()
        if 'BLENDER_RENDER' in getattr(panel, 'COMPAT_ENGINES', ())
        and getattr(panel, 'bl_context', None) not in exclude_contexts
        and not panel.__name__.startswith(exclude_prefixes)
    ]


classes = (
    PCVR_RENDER_PT_xray,
    PCVR_RENDER_PT_splatting,
    PCVR_RENDER_PT_film,
    PCVR_RENDER_PT_passes,
    PCVR_DATA_PT_volume,
)


_register_classes, _unregister_classes = bpy.utils.register_classes_factory(classes)


def register():
    _register_classes()
    for panel in get_panels():
        panel.COMPAT_ENGINES.add('PCVR')


def unregister():
    _unregister_classes()
    for panel in get_panels():
        panel.COMPAT_ENGINES.discard('PCVR')
