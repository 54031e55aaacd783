"""Panels: the built-in ones PCVR shares, and the magnification estimate of the render panel."""

from types import SimpleNamespace

import bpy
import pcvr_native as pn
import pytest

import blender_scenes as bs
import pcvr_addon
from pcvr_addon import cache, engine, ui


def test_shares_output_dimensions_color_management_and_camera_panels():
    shared = {panel.__name__ for panel in bpy.types.Panel.__subclasses__()
              if 'PCVR' in getattr(panel, 'COMPAT_ENGINES', ())}
    assert {'RENDER_PT_format', 'RENDER_PT_frame_range', 'RENDER_PT_output', 'RENDER_PT_color_management',
            'RENDER_PT_post_processing', 'DATA_PT_lens', 'DATA_PT_volume_file'} <= shared
    # Settings PCVR ignores stay hidden.
    assert not {'RENDER_PT_simplify', 'RENDER_PT_freestyle', 'MATERIAL_PT_custom_props', 'WORLD_PT_context_world',
                'DATA_PT_volume_render', 'DATA_PT_light'} & shared
    assert {'PCVR_RENDER_PT_xray', 'PCVR_RENDER_PT_splatting', 'PCVR_RENDER_PT_film', 'PCVR_RENDER_PT_passes',
            'PCVR_DATA_PT_volume'} <= {cls.__name__ for cls in ui.classes}


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
    bpy.ops.pcvr.frame_volume(magnification=3.0)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    cache.grids.clear()  # frame_volume read it

    assert engine.sampling_estimate(depsgraph, scene.pcvr) == (None, [], 1)
    assert cache.grids.stats.reads == 0
    bs.render(scene)
    magnification, strides, unread = engine.sampling_estimate(depsgraph, scene.pcvr)
    assert magnification == pytest.approx((3.0, 3.0))
    assert unread == 0 and len(strides) <= 1


class Layout:
    """Stands in for UILayout (there is none without a window): records the properties drawn and
    checks that they exist."""

    def __init__(self, drawn):
        self.drawn = drawn

    def __getattr__(self, name):  # use_property_split, active, ...
        return None

    def column(self, **kwargs):
        return self

    def prop(self, data, name, **kwargs):
        assert name in data.bl_rna.properties, f"{data} has no property {name}"
        self.drawn.append(name)

    def prop_search(self, data, name, search_data, search_name, **kwargs):
        assert search_name in search_data.bl_rna.properties
        self.prop(data, name)

    def label(self, text="", **kwargs):
        self.drawn.append(text)

    def operator(self, idname, **kwargs):
        category, name = idname.split(".")
        getattr(getattr(bpy.ops, category), name).get_rna_type()  # KeyError when not registered
        self.drawn.append(idname)


def draw(panel, context):
    drawn = []
    panel.draw(type("Panel", (), {"layout": Layout(drawn)})(), context)
    return drawn


@pytest.mark.parametrize("method, hidden", [('REGULAR', {"post_filter", "subgrid_stride"}),
                                            ('PCVR', set()),
                                            ('BILINEAR_SPREAD', {"splat_kernel"})])
def test_panels_draw_only_settings_in_use(tmp_path, method, hidden):
    scene = bs.setup(method=method)
    obj = bs.add_volume("Box", bs.write_vdb(tmp_path / "box.vdb", bs.box()))
    context = SimpleNamespace(scene=scene, view_layer=bpy.context.view_layer, volume=obj.data, engine='PCVR',
                              evaluated_depsgraph_get=bpy.context.evaluated_depsgraph_get)

    settings = {"method", "splat_kernel", "post_filter", "subgrid_stride"}
    splatting = draw(ui.PCVR_RENDER_PT_splatting, context)
    assert settings & set(splatting) == settings - hidden
    assert "No scene camera" in splatting
    assert {"mode", "xray_gain"} <= set(draw(ui.PCVR_RENDER_PT_xray, context))
    assert draw(ui.PCVR_RENDER_PT_film, context) == ["film_transparent"]
    assert draw(ui.PCVR_RENDER_PT_passes, context) == ["use_pass_xray"]
    assert draw(ui.PCVR_DATA_PT_volume, context) == ["grid", "density_scale", "pcvr.frame_volume"]
