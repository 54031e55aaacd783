# SPDX-License-Identifier: GPL-3.0-or-later

"""Panels of the PCVR settings, and the built-in panels PCVR shares."""

import bpy
from bpy.types import Panel, UIList

from bl_ui.utils import PresetPanel

from ..render import native_render, statistics
from ..scene import lighting, scene_inputs
from . import presets
from .properties import scatters


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


class PCVRRenderPanel(PCVRButtonsPanel):
    """A panel of the PCVR render settings, drawn in some modes only."""
    modes = {'XRAY', 'SHADED', 'MIP'}

    @classmethod
    def poll(cls, context):
        return super().poll(context) and context.scene.pcvr.mode in cls.modes


class PCVR_RENDER_PT_pcvr(PCVRRenderPanel, Panel):
    bl_label = "PCVR"

    def draw(self, context):
        layout = property_split(self.layout)
        settings = context.scene.pcvr
        layout.prop(settings, "mode")
        if settings.mode == 'XRAY':
            layout.prop(settings, "use_auto_exposure")
            row = layout.row()
            row.active = not settings.use_auto_exposure
            row.prop(settings, "xray_gain")
        elif settings.mode == 'MIP':
            layout.prop(settings, "mip_color")
        else:
            layout.prop(settings, "shadows")


class PCVR_RENDER_PT_method(PCVRRenderPanel, Panel):
    bl_label = "Method"
    bl_parent_id = "PCVR_RENDER_PT_pcvr"

    def draw(self, context):
        layout = property_split(self.layout)
        settings = context.scene.pcvr
        col = layout.column()
        col.prop(settings, "method")
        # Only the settings the chosen method and mode use: bilinear spreading has no splat kernel, regular
        # splatting no subgrid, X-ray no sheets.
        if settings.method != 'BILINEAR_SPREAD':
            col.prop(settings, "splat_kernel")
        if settings.method != 'REGULAR':
            col.prop(settings, "post_filter" if settings.mode == 'XRAY' else "sheet_post_filter")
            col.prop(settings, "subgrid_stride", text="Stride")
        if settings.mode == 'XRAY' and settings.method != 'BILINEAR_SPREAD':
            col.prop(settings, "passband")
        if settings.mode != 'XRAY':
            col = layout.column()
            col.prop(settings, "sheet_spacing")
        if settings.mode == 'SHADED':
            col.prop(settings, "samples_per_sheet")
            col.prop(settings, "opacity_cutoff")
            if settings.method == 'PCVR':
                col.prop(settings, "sheet_fill")

        draw_sampling_estimate(layout.column(align=True), context)


class PCVR_RENDER_PT_memory(PCVRRenderPanel, Panel):
    bl_label = "Memory"
    bl_parent_id = "PCVR_RENDER_PT_pcvr"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = property_split(self.layout)
        layout.prop(context.scene.pcvr, "stream_above", text="Stream Above (MiB)")


class PCVR_RENDER_PT_statistics(PCVRRenderPanel, Panel):
    bl_label = "Last Render"
    bl_parent_id = "PCVR_RENDER_PT_pcvr"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = self.layout
        last = statistics.last_render.get(context.scene.session_uid)
        if last is None:
            layout.label(text="Render to see what was splatted and culled", icon='INFO')
            return
        mode, stats = last
        grid = layout.grid_flow(row_major=True, columns=2, even_columns=False, align=True)
        for label, value in statistics.statistics_rows(mode, stats):
            grid.label(text=label)
            grid.label(text=value)


def draw_sampling_estimate(layout, context):
    """The magnification (and stride) the volumes in view get, as far as known without reading files."""
    settings = context.scene.pcvr
    try:
        estimate = native_render.sampling_estimate(context.evaluated_depsgraph_get(), settings)
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
            text += ", stride " + statistics.format_strides(strides)
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
        if context.scene.pcvr.mode == 'SHADED':
            col.prop(context.view_layer, "use_pass_z", text="Depth")
        col.prop(context.view_layer.pcvr, "use_pass_xray")


class VolumePanel(PCVRButtonsPanel):
    """A panel of the volume's data properties."""
    bl_context = "data"

    @classmethod
    def poll(cls, context):
        return context.volume and super().poll(context)


class PCVR_DATA_PT_volume(VolumePanel, Panel):
    bl_label = "PCVR"

    def draw(self, context):
        layout = property_split(self.layout)
        volume = context.volume
        settings = volume.pcvr
        layout.prop_search(settings, "grid", volume, "grids", icon='VOLUME_DATA')
        layout.prop(settings, "density_scale")
        if context.scene.pcvr.mode == 'SHADED':
            layout.prop(settings, "source")
        if context.scene.pcvr.mode == 'XRAY' or context.view_layer.pcvr.use_pass_xray:
            layout.prop(settings, "xray_values")
            if settings.xray_values == 'HOUNSFIELD':
                layout.prop(settings, "mu_water")
        layout.operator("pcvr.frame_volume", icon='CAMERA_DATA')
        layout.operator("pcvr.c_arm_view", icon='VIEW_PERSPECTIVE')


class PCVR_UL_clip_planes(UIList):
    """A volume's clip planes: the object of each, and whether it cuts."""

    def draw_item(self, _context, layout, _data, item, _icon, _active_data, _active_property, _index=0, _flt=0):
        row = layout.row(align=True)
        row.prop(item, "enabled", text="")
        row.prop(item, "object", text="", emboss=False, icon='EMPTY_SINGLE_ARROW')


class VolumeSubPanel(VolumePanel):
    """A sub-panel of the volume's PCVR panel."""
    bl_parent_id = "PCVR_DATA_PT_volume"


class PCVR_DATA_PT_clipping(VolumeSubPanel, Panel):
    """The volume's crop box and clip planes (every mode)."""
    bl_label = "Clipping"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = property_split(self.layout)
        settings = context.volume.pcvr
        row = layout.row(heading="Crop")
        row.prop(settings, "use_crop", text="")
        sub = row.row()
        sub.active = settings.use_crop
        sub.prop(settings, "crop_object", text="")
        layout.operator("pcvr.add_crop_box", icon='CUBE')

        layout = self.layout
        layout.label(text="Clip Planes (each keeps its +Z side)")
        row = layout.row()
        row.template_list("PCVR_UL_clip_planes", "", settings, "clip_planes", settings, "clip_plane_index", rows=3)
        col = row.column(align=True)
        col.operator("pcvr.add_clip_plane", icon='ADD', text="")
        col.operator("pcvr.remove_clip_plane", icon='REMOVE', text="")


class PCVR_PT_transfer_function_presets(PresetPanel, Panel):
    """Blender's preset menu, listing the presets shipped with the add-on as well as the user's."""
    bl_label = "Transfer Function Presets"
    preset_subdir = presets.SUBDIR
    preset_operator = "script.execute_preset"
    preset_add_operator = "pcvr.transfer_function_preset_add"

    def draw(self, context):
        layout = self.layout
        layout.emboss = 'PULLDOWN_MENU'
        layout.operator_context = 'EXEC_DEFAULT'
        self.path_menu(presets.search_paths(), self.preset_operator, add_operator=self.preset_add_operator,
                       filter_ext=lambda extension: extension.lower() == ".py",
                       display_name=presets.display_name)


class VolumeSheetPanel(VolumeSubPanel):
    """A sub-panel of the volume's PCVR panel for the shaded and MIP modes."""
    modes = {'SHADED', 'MIP'}

    @classmethod
    def poll(cls, context):
        return super().poll(context) and context.scene.pcvr.mode in cls.modes


class PCVR_DATA_PT_transfer_function(VolumeSheetPanel, Panel):
    bl_label = "Transfer Function"

    def draw_header_preset(self, _context):
        PCVR_PT_transfer_function_presets.draw_panel_header(self.layout)

    def draw(self, context):
        layout = self.layout
        settings = context.volume.pcvr
        layout.template_ID(settings, "transfer_function", new="pcvr.transfer_function_new")
        if settings.ramp is not None:
            layout.template_color_ramp(settings.transfer_function, "color_ramp", expand=True)
        else:
            layout.label(text="Grey ramp, 5% opacity per voxel at the top", icon='INFO')

        layout = property_split(layout)
        layout.prop(settings, "use_grid_range")
        col = layout.column(align=True)
        col.active = not settings.use_grid_range
        col.prop(settings, "tf_min")
        col.prop(settings, "tf_max")
        layout.operator("pcvr.transfer_function_range_from_grid", icon='IMPORT')
        if context.scene.pcvr.mode == 'SHADED':
            layout.prop(settings, "opacity_scale")


class PCVR_DATA_PT_gradient_opacity(VolumeSheetPanel, Panel):
    bl_label = "Gradient Opacity"
    bl_options = {'DEFAULT_CLOSED'}
    modes = {'SHADED'}

    def draw_header(self, context):
        self.layout.prop(context.volume.pcvr, "use_gradient_opacity", text="")

    def draw(self, context):
        layout = self.layout
        settings = context.volume.pcvr
        layout.active = settings.use_gradient_opacity
        layout.template_ID(settings, "gradient_opacity", new="pcvr.gradient_opacity_new")
        if settings.gradient_ramp is not None:
            layout.template_color_ramp(settings.gradient_opacity, "color_ramp", expand=True)
        else:
            layout.label(text="Transparent where uniform, opaque from Max Gradient", icon='INFO')
        property_split(layout).prop(settings, "gradient_max")
        layout.operator("pcvr.gradient_max_from_grid", icon='IMPORT')


def light_paths_label(scene):
    """What Scattering Octaves 0 renders: the octaves the scene's Light Paths give."""
    octaves = scene_inputs.light_paths_octaves(scene)
    return ("From Light Paths: single scattering" if octaves == 1 else
            f"From Light Paths: {octaves} octaves")


class PCVR_DATA_PT_shading(VolumeSheetPanel, Panel):
    bl_label = "Shading"
    modes = {'SHADED'}

    def draw_header(self, context):
        self.layout.prop(context.volume.pcvr, "use_shading", text="")

    def draw(self, context):
        layout = property_split(self.layout)
        settings = context.volume.pcvr
        layout.active = settings.use_shading
        layout.prop(settings, "shading_model")
        layout.prop(settings, "ambient_occlusion")
        col = layout.column(align=True)
        if scatters(settings):
            col.prop(settings, "scattering_octaves")
            if settings.scattering_octaves == 0:
                col.label(text=light_paths_label(context.scene), icon='INFO')
        if settings.shading_model == 'SCATTER':
            col.prop(settings, "anisotropy")
            return
        col.prop(settings, "ambient")
        col.prop(settings, "diffuse")
        col.prop(settings, "specular")
        col.prop(settings, "shininess")


class PCVR_LIGHT_PT_light(PCVRButtonsPanel, Panel):
    """The light settings shaded mode uses (Blender's own light panels belong to Cycles and EEVEE)."""
    bl_label = "Light"
    bl_context = "data"

    @classmethod
    def poll(cls, context):
        return context.light and super().poll(context) and context.scene.pcvr.mode == 'SHADED'

    def draw(self, context):
        layout = self.layout
        light = context.light
        layout.row().prop(light, "type", expand=True)
        layout = property_split(layout)
        col = layout.column()
        if "use_temperature" in light.bl_rna.properties:
            row = col.row(heading="Temperature", align=True)
            row.prop(light, "use_temperature", text="")
            sub = row.row()
            sub.active = light.use_temperature
            sub.prop(light, "temperature", text="")
        col.prop(light, "color")
        col.prop(light, "energy")
        for name in ("exposure", "normalize"):
            if name in light.bl_rna.properties:
                col.prop(light, name)
        if light.type in {'SPOT', 'AREA'}:
            layout.label(text="Lights as a point light: no cone, no size", icon='INFO')


class PCVR_WORLD_PT_ambient(PCVRButtonsPanel, Panel):
    """The world colour: the ambient light of shaded mode and the background of an opaque film."""
    bl_label = "Ambient"
    bl_context = "world"

    @classmethod
    def poll(cls, context):
        return context.world and super().poll(context) and context.scene.pcvr.mode in {'SHADED', 'MIP'}

    def draw(self, context):
        layout = property_split(self.layout)
        world = context.world
        background = lighting.world_background_node(world)
        if background is None:
            layout.prop(world, "color")
            return
        for name in ("Color", "Strength"):
            socket = background.inputs[name]
            row = layout.row()
            row.active = not socket.is_linked
            row.prop(socket, "default_value", text=name)


def get_panels():
    """The built-in panels that PCVR shares with Blender's own engines, less those whose settings PCVR
    ignores (materials, light probes, Freestyle, Grease Pencil, Simplify, stereoscopy, EEVEE's volume
    settings) and those it replaces with its own (the light's settings)."""
    exclude_contexts = {'material'}
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
    PCVR_RENDER_PT_pcvr,
    PCVR_RENDER_PT_method,
    PCVR_RENDER_PT_memory,
    PCVR_RENDER_PT_statistics,
    PCVR_RENDER_PT_film,
    PCVR_RENDER_PT_passes,
    PCVR_DATA_PT_volume,
    PCVR_UL_clip_planes,
    PCVR_DATA_PT_clipping,
    PCVR_PT_transfer_function_presets,
    PCVR_DATA_PT_transfer_function,
    PCVR_DATA_PT_gradient_opacity,
    PCVR_DATA_PT_shading,
    PCVR_LIGHT_PT_light,
    PCVR_WORLD_PT_ambient,
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
