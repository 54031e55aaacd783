"""Panels: the built-in ones PCVR shares, and the magnification estimate of the render panel."""

import os
from types import SimpleNamespace

import bpy
import pcvr_native as pn
import pytest

import blender_scenes as bs
import pcvr_addon
from pcvr_addon.ui import panels as ui, presets
from pcvr_addon.render import cache, native_render, statistics


def test_shares_output_dimensions_color_management_and_camera_panels():
    shared = {panel.__name__ for panel in bpy.types.Panel.__subclasses__()
              if 'PCVR' in getattr(panel, 'COMPAT_ENGINES', ())}
    assert {'RENDER_PT_format', 'RENDER_PT_frame_range', 'RENDER_PT_output', 'RENDER_PT_color_management',
            'RENDER_PT_post_processing', 'DATA_PT_lens', 'DATA_PT_volume_file', 'WORLD_PT_context_world',
            'DATA_PT_context_light'} <= shared
    # Settings PCVR ignores, or draws itself (the light's), stay hidden.
    assert not {'RENDER_PT_simplify', 'RENDER_PT_freestyle', 'MATERIAL_PT_custom_props', 'DATA_PT_volume_render',
                'DATA_PT_light', 'DATA_PT_spot'} & shared
    assert {'PCVR_RENDER_PT_pcvr', 'PCVR_RENDER_PT_method', 'PCVR_RENDER_PT_statistics', 'PCVR_RENDER_PT_film',
            'PCVR_RENDER_PT_passes', 'PCVR_DATA_PT_volume', 'PCVR_DATA_PT_transfer_function', 'PCVR_DATA_PT_shading',
            'PCVR_LIGHT_PT_light', 'PCVR_WORLD_PT_ambient'} <= {cls.__name__ for cls in ui.classes}


def test_unregister_removes_pcvr_from_shared_panels():
    pcvr_addon.unregister()
    try:
        assert 'PCVR' not in bpy.types.RENDER_PT_format.COMPAT_ENGINES
    finally:
        pcvr_addon.register()


@pytest.mark.skipif(not hasattr(pn, "effective_magnification"), reason="pcvr_native lacks effective_magnification")
def test_sampling_estimate_uses_cached_grids_only(tmp_path):
    scene = bs.setup(method='PCVR')
    obj = bs.add_volume("Box", bs.write_vdb(tmp_path / "box.vdb", bs.box()))
    bpy.context.view_layer.objects.active = obj
    bpy.ops.pcvr.frame_volume(magnification=3.0, set_resolution=True)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    cache.grids.clear()  # frame_volume read it

    assert native_render.sampling_estimate(depsgraph, scene.pcvr) == (None, [], 1)
    assert cache.grids.stats.reads == 0
    bs.render(scene)
    magnification, strides, unread = native_render.sampling_estimate(depsgraph, scene.pcvr)
    assert magnification == pytest.approx((3.0, 3.0))
    assert unread == 0 and len(strides) <= 1


class Layout:
    """Stands in for UILayout (there is none without a window): records the properties and widgets drawn
    and checks that they exist."""

    def __init__(self, drawn):
        self.drawn = drawn

    def __getattr__(self, name):  # use_property_split, active, ...
        return None

    def column(self, **kwargs):
        return self

    row = grid_flow = column

    def prop(self, data, name, **kwargs):
        assert name in data.bl_rna.properties, f"{data} has no property {name}"
        self.drawn.append(name)

    def prop_search(self, data, name, search_data, search_name, **kwargs):
        assert search_name in search_data.bl_rna.properties
        self.prop(data, name)

    def template_ID(self, data, name, new="", **kwargs):
        self.prop(data, name)
        self.operator(new)

    def template_list(self, list_type, list_id, data, name, active_data, active_name, **kwargs):
        assert hasattr(bpy.types, list_type), f"no list {list_type}"
        assert name in data.bl_rna.properties and active_name in active_data.bl_rna.properties
        self.drawn.append(name)

    def template_color_ramp(self, data, name, **kwargs):
        assert isinstance(getattr(data, name), bpy.types.ColorRamp)
        self.drawn.append("color_ramp")

    def popover(self, panel, **kwargs):
        assert hasattr(bpy.types, panel), f"no panel {panel}"
        self.drawn.append(panel)

    def label(self, text="", **kwargs):
        self.drawn.append(text)

    def operator(self, idname, **kwargs):
        category, name = idname.split(".")
        getattr(getattr(bpy.ops, category), name).get_rna_type()  # KeyError when not registered
        self.drawn.append(idname)


def draw(panel, context, method="draw"):
    drawn = []
    getattr(panel, method)(type("Panel", (), {"layout": Layout(drawn)})(), context)
    return drawn


def panel_context(scene, **members):
    return SimpleNamespace(scene=scene, view_layer=bpy.context.view_layer, engine='PCVR',
                           evaluated_depsgraph_get=bpy.context.evaluated_depsgraph_get, **members)


SHEET_SETTINGS = {"sheet_post_filter", "sheet_spacing", "samples_per_sheet", "opacity_cutoff", "sheet_fill"}
ALL = {"method", "splat_kernel", "post_filter", "subgrid_stride"} | SHEET_SETTINGS


@pytest.mark.parametrize("mode, method, shown", [
    ('XRAY', 'REGULAR', {"method", "splat_kernel"}),
    ('XRAY', 'PCVR', {"method", "splat_kernel", "post_filter", "subgrid_stride"}),
    ('XRAY', 'BILINEAR_SPREAD', {"method", "post_filter", "subgrid_stride"}),
    ('SHADED', 'PCVR', {"method", "splat_kernel", "subgrid_stride"} | SHEET_SETTINGS),  # sheet_fill: post-convolved only
    ('SHADED', 'REGULAR', {"method", "splat_kernel", "sheet_spacing", "samples_per_sheet", "opacity_cutoff"}),
    ('MIP', 'PCVR', {"method", "splat_kernel", "sheet_post_filter", "subgrid_stride", "sheet_spacing"}),  # MIP splats
])
def test_method_panel_draws_only_settings_in_use(tmp_path, mode, method, shown):
    scene = bs.setup(method=method)
    scene.pcvr.mode = mode
    bs.add_volume("Box", bs.write_vdb(tmp_path / "box.vdb", bs.box()))
    drawn = draw(ui.PCVR_RENDER_PT_method, panel_context(scene))
    assert ALL & set(drawn) == shown
    assert "No scene camera" in drawn


@pytest.mark.parametrize("mode", ['XRAY', 'SHADED', 'MIP'])
def test_panels_of_each_mode(tmp_path, mode):
    scene = bs.setup()
    scene.pcvr.mode = mode
    obj = bs.add_volume("Box", bs.write_vdb(tmp_path / "box.vdb", bs.box()))
    light = bpy.data.lights.new("Spot", 'SPOT')
    world = bpy.data.worlds.new("World")
    context = panel_context(scene, volume=obj.data, light=light, world=world)

    main = draw(ui.PCVR_RENDER_PT_pcvr, context)
    assert main[0] == "mode" and ("xray_gain" in main) == (mode == 'XRAY') and ("mip_color" in main) == (mode == 'MIP')
    assert draw(ui.PCVR_RENDER_PT_film, context) == ["film_transparent"]
    assert draw(ui.PCVR_RENDER_PT_passes, context) == (["use_pass_z", "use_pass_xray"] if mode == 'SHADED'
                                                       else ["use_pass_xray"])
    # What the X-ray integrates, where an X-ray is rendered (every mode here: bs.setup turns the XRay pass on).
    # Shaded mode also says what gives the volume its colour: the transfer function or the material.
    assert draw(ui.PCVR_DATA_PT_volume, context) == ["grid", "density_scale"] + (["source"] if mode == 'SHADED' else []) + [
        "xray_values", "pcvr.frame_volume", "pcvr.c_arm_view"]
    obj.data.pcvr.xray_values = 'HOUNSFIELD'
    assert "mu_water" in draw(ui.PCVR_DATA_PT_volume, context)
    obj.data.pcvr.xray_values = 'DENSITY'
    context.view_layer.pcvr.use_pass_xray = False
    assert ("xray_values" in draw(ui.PCVR_DATA_PT_volume, context)) == (mode == 'XRAY')
    context.view_layer.pcvr.use_pass_xray = True

    sheets = mode in {'SHADED', 'MIP'}
    assert ui.PCVR_DATA_PT_transfer_function.poll(context) == sheets
    assert ui.PCVR_DATA_PT_shading.poll(context) == (mode == 'SHADED')
    assert ui.PCVR_DATA_PT_gradient_opacity.poll(context) == (mode == 'SHADED')
    assert ui.PCVR_LIGHT_PT_light.poll(context) == (mode == 'SHADED')
    assert ui.PCVR_WORLD_PT_ambient.poll(context) == sheets
    if not sheets:
        return
    assert draw(ui.PCVR_DATA_PT_transfer_function, context, "draw_header_preset") == [
        "PCVR_PT_transfer_function_presets"]
    transfer = draw(ui.PCVR_DATA_PT_transfer_function, context)
    assert transfer[:2] == ["transfer_function", "pcvr.transfer_function_new"] and "color_ramp" not in transfer
    assert {"use_grid_range", "tf_min", "tf_max", "pcvr.transfer_function_range_from_grid"} <= set(transfer)
    assert ("opacity_scale" in transfer) == (mode == 'SHADED')
    obj.data.pcvr.ensure_transfer_function()
    assert "color_ramp" in draw(ui.PCVR_DATA_PT_transfer_function, context)
    if mode == 'SHADED':
        assert draw(ui.PCVR_DATA_PT_shading, context, "draw_header") == ["use_shading"]
        assert draw(ui.PCVR_DATA_PT_shading, context) == ["shading_model", "ambient_occlusion", "ambient", "diffuse",
                                                          "specular", "shininess"]
        obj.data.pcvr.shading_model = 'SCATTER'
        scene.cycles.volume_bounces = 0
        assert draw(ui.PCVR_DATA_PT_shading, context) == ["shading_model", "ambient_occlusion", "scattering_octaves",
                                                          "From Light Paths: single scattering", "anisotropy"]
        scene.cycles.volume_bounces, scene.cycles.max_bounces = 3, 12
        assert "From Light Paths: 4 octaves" in draw(ui.PCVR_DATA_PT_shading, context)
        obj.data.pcvr.scattering_octaves = 2  # an explicit number: nothing derived to show
        assert draw(ui.PCVR_DATA_PT_shading, context) == ["shading_model", "ambient_occlusion", "scattering_octaves",
                                                          "anisotropy"]
        assert draw(ui.PCVR_DATA_PT_gradient_opacity, context, "draw_header") == ["use_gradient_opacity"]
        gradient = draw(ui.PCVR_DATA_PT_gradient_opacity, context)
        assert gradient[:2] == ["gradient_opacity", "pcvr.gradient_opacity_new"]
        assert gradient[-2:] == ["gradient_max", "pcvr.gradient_max_from_grid"]
        obj.data.pcvr.ensure_gradient_opacity()
        assert "color_ramp" in draw(ui.PCVR_DATA_PT_gradient_opacity, context)
        lit = draw(ui.PCVR_LIGHT_PT_light, context)
        assert {"type", "color", "energy"} <= set(lit) and "Lights as a point light: no cone, no size" in lit
    world_drawn = draw(ui.PCVR_WORLD_PT_ambient, context)
    assert world_drawn in (["color"], ["default_value", "default_value"])


def test_clipping_panel(tmp_path):
    scene = bs.setup()
    obj = bs.add_volume("Box", bs.write_vdb(tmp_path / "box.vdb", bs.box()))
    context = panel_context(scene, volume=obj.data)
    assert ui.PCVR_DATA_PT_clipping.poll(context)
    assert draw(ui.PCVR_DATA_PT_clipping, context) == [
        "use_crop", "crop_object", "pcvr.add_crop_box", "Clip Planes (each keeps its +Z side)", "clip_planes",
        "pcvr.add_clip_plane", "pcvr.remove_clip_plane"]
    drawn = []
    item = obj.data.pcvr.clip_planes.add()
    ui.PCVR_UL_clip_planes.draw_item(None, context, Layout(drawn), obj.data.pcvr, item, 0, obj.data.pcvr,
                                     "clip_plane_index")
    assert drawn == ["enabled", "object"]


def test_statistics_panel_shows_the_last_render(tmp_path):
    scene = bs.setup()
    scene.pcvr.mode = 'SHADED'
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=2.0)
    bs.add_volume("Box", bs.write_vdb(tmp_path / "box.vdb", bs.box()))
    context = panel_context(scene)
    assert draw(ui.PCVR_RENDER_PT_statistics, context) == ["Render to see what was splatted and culled"]
    bs.render(scene)
    drawn = draw(ui.PCVR_RENDER_PT_statistics, context)
    assert drawn[:2] == ["Blocks", f"{statistics.last_render[scene.session_uid][1]['blocks']:,}"]
    assert "Transparent" in drawn and "Behind opaque" in drawn


def test_preset_menu_lists_shipped_and_user_presets(tmp_path, monkeypatch):
    """The preset popover's listing (Menu.path_menu), fed the shipped folder and the user's."""
    monkeypatch.setenv("BLENDER_USER_SCRIPTS", str(tmp_path))
    user = tmp_path / "presets" / presets.SUBDIR
    user.mkdir(parents=True)
    (user / "My_Smoke.py").write_text("")
    listed = []

    def path_menu(paths, operator, **kwargs):
        assert operator == "script.execute_preset"
        assert kwargs["add_operator"] == "pcvr.transfer_function_preset_add"
        listed.extend(kwargs["display_name"](name) for path in paths for name in sorted(os.listdir(path)))

    panel = SimpleNamespace(layout=SimpleNamespace(), path_menu=path_menu, preset_operator="script.execute_preset",
                            preset_add_operator="pcvr.transfer_function_preset_add")
    ui.PCVR_PT_transfer_function_presets.draw(panel, None)
    assert "CT Bone" in listed and "My Smoke" in listed
