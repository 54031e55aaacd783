# SPDX-License-Identifier: GPL-3.0-or-later

"""The native renderers' defaults, in one table: the add-on's settings take their defaults from here.

pcvr_native is still tuned (sheet spacing, samples per sheet and the shaded post filter may change), so
tests/addon/test_defaults.py compares this table with the defaults in pcvr_native's own signatures: a change
there fails that test until it is made here too, and the interface, the command line and scripts follow.
Names and values are pcvr_native's keyword arguments.

NATIVE_NAMES spells the settings' enum items (ui/properties.py) as pcvr_native and the command line do.
"""

# render_xray
XRAY = {
    "method": "pcvr",
    "splat_kernel": "gauss1.4",
    "post_filter": "bilinear",
    "stride": 0,
    "passband": "compensated",
}

# render_shaded, and render_mip for the arguments it shares
SHEETS = {
    "method": "pcvr",
    "splat_kernel": "gauss1.4",
    "post_filter": "catmull_rom",
    "stride": 0,
    "sheet_spacing": 1.0,
    "samples_per_sheet": 2,
    "opacity_cutoff": 0.99,
    "sheet_fill": "auto",  # render_shaded only
}

# pcvr_native.Shading(): the Blinn-Phong material, VTK's and 3D Slicer's usual one
MATERIAL = {
    "ambient": 0.1,
    "diffuse": 0.9,
    "specular": 0.2,
    "shininess": 10.0,
}

# How pcvr_native and the command line spell the enum items of the settings (ui/properties.py).
NATIVE_NAMES = {
    'REGULAR': "regular",
    'PCVR': "pcvr",
    'BILINEAR_SPREAD': "bilinear_spread",
    'GAUSS_1_4': "gauss1.4",
    'GAUSS_2_0': "gauss2.0",
    'LINEAR': "linear",
    'BOX': "box",
    'BILINEAR': "bilinear",
    'CATMULL_ROM': "catmull_rom",
    'COMPENSATED': "compensated",
    'PAPER': "paper",
    'AUTO': "auto",
    'SPLAT': "splat",
    'SAMPLE': "sample",
}


def identifier(native_name):
    """The enum identifier of a pcvr_native name."""
    return next(key for key, value in NATIVE_NAMES.items() if value == native_name)
