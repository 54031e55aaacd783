"""The add-on's defaults are pcvr_native's: defaults.py against the native signatures, and the settings'
defaults against defaults.py. When the native core changes a default, the first test says what to change."""

import re

import bpy
import pcvr_native as pn
import pytest

from pcvr_addon.scene import defaults
from pcvr_addon.scene.defaults import NATIVE_NAMES


def native_defaults(function):
    """{argument: default} of a nanobind function, from its signature (`name: type = \\N` refers to the N-th
    of the defaults nanobind keeps beside it)."""
    [(signature, _doc, values)] = function.__nb_signature__
    return {name: values[int(index)] for name, index in re.findall(r"(\w+): [^=,]+ = \\(\d+)", signature)}


@pytest.mark.parametrize("table, function", [(defaults.XRAY, pn.render_xray), (defaults.SHEETS, pn.render_shaded),
                                             (defaults.SHEETS, pn.render_mip)])
def test_table_holds_the_native_defaults(table, function):
    native = native_defaults(function)
    shared = {name: value for name, value in table.items() if name in native}
    assert shared == {name: native[name] for name in shared}
    assert set(table) - set(shared) <= {"samples_per_sheet", "opacity_cutoff", "sheet_fill"}  # render_mip has none


def test_material_is_the_native_shading():
    shading = pn.Shading()
    assert {name: getattr(shading, name) for name in defaults.MATERIAL} == defaults.MATERIAL


def property_default(struct, name):
    prop = struct.bl_rna.properties[name]
    return NATIVE_NAMES.get(prop.default, prop.default) if prop.type == 'ENUM' else pytest.approx(prop.default)


@pytest.mark.parametrize("setting, table, name", [
    ("method", defaults.XRAY, "method"),
    ("splat_kernel", defaults.XRAY, "splat_kernel"),
    ("post_filter", defaults.XRAY, "post_filter"),
    ("subgrid_stride", defaults.XRAY, "stride"),
    ("passband", defaults.XRAY, "passband"),
    ("sheet_post_filter", defaults.SHEETS, "post_filter"),
    ("sheet_spacing", defaults.SHEETS, "sheet_spacing"),
    ("samples_per_sheet", defaults.SHEETS, "samples_per_sheet"),
    ("opacity_cutoff", defaults.SHEETS, "opacity_cutoff"),
    ("sheet_fill", defaults.SHEETS, "sheet_fill"),
])
def test_scene_settings_default_to_the_table(setting, table, name):
    assert property_default(bpy.types.Scene.bl_rna.properties["pcvr"].fixed_type, setting) == table[name]


@pytest.mark.parametrize("name", defaults.MATERIAL)
def test_volume_material_defaults_to_the_table(name):
    assert property_default(bpy.types.Volume.bl_rna.properties["pcvr"].fixed_type, name) == defaults.MATERIAL[name]


def test_sheet_methods_share_the_xray_defaults():
    """method, splat_kernel and stride are one setting each for every mode, so their defaults must agree."""
    for name in ("method", "splat_kernel", "stride"):
        assert defaults.XRAY[name] == defaults.SHEETS[name]
