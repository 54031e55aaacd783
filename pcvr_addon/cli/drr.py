# SPDX-License-Identifier: GPL-3.0-or-later

"""C-arm (cone-beam) DRRs from the command line: the --cone-beam options, the scene camera they make (the operator
pcvr.c_arm_view, pcvr_native.cameras.cone_beam's geometry); io.image_io.write_drr writes the images.

    python -m pcvr_addon render ct_study/ -o drr.tif --cone-beam 1000 1500 --detector 512x512 --pixel-spacing 0.8 0.8
    python -m pcvr_addon render ct.vdb -o drr/ct_###.png --cone-beam 1000 1500 --angles 0:360:2 --intensity 60000

The volume's world units are millimetres (a scan's LPS millimetres; a .vdb's units are taken as such). The image is
the line integral of the attenuation along each ray (.exr, or a float .tif), or with --intensity I0 the detected
intensity I0 exp(-line integral) (.exr as float; .png and .tif as 16-bit integers, rounded and clipped to 0..65535).
"""

import math
import os

import bpy

from ..io import image_io

# The options this module adds (cli names); all but --intensity set the camera.
OPTIONS = ("cone_beam", "detector", "pixel_spacing", "gantry", "tilt", "isocentre", "detector_offset", "intensity")
# Options of the render command that place an orthographic camera, which a C-arm replaces.
FRAMING_OPTIONS = ("view", "view_direction", "magnification")


def add_arguments(render, detector_type):
    """The C-arm options of the render command's argparse parser; `detector_type` parses COLSxROWS."""
    group = render.add_argument_group("C-arm DRR (cone beam, millimetres and degrees; see docs/drr.md)")
    group.add_argument("--cone-beam", type=float, nargs=2, metavar=("SAD", "SID"),
                       help="a radiograph from an X-ray source SAD from the isocentre onto a flat detector SID from "
                            "the source (.vdb or scan; X-ray mode)")
    group.add_argument("--detector", type=detector_type, metavar="COLSxROWS",
                       help="the detector's pixels (default 512x512)")
    group.add_argument("--pixel-spacing", type=float, nargs=2, metavar=("DU", "DV"),
                       help="a detector pixel's width and height (default 0.8 0.8)")
    group.add_argument("--gantry", type=float, metavar="DEG", help="gantry angle: 0 puts the source in front "
                       "(anterior, -y), 90 at the patient's left (+x) (default 0); --angles sweeps it")
    group.add_argument("--tilt", type=float, metavar="DEG", help="the source turned towards +z (head) out of the "
                       "gantry's plane (default 0)")
    group.add_argument("--isocentre", type=float, nargs=3, metavar=("X", "Y", "Z"),
                       help="where the central ray passes, world millimetres (default: the volume's centre)")
    group.add_argument("--detector-offset", type=float, nargs=2, metavar=("U", "V"),
                       help="the detector's centre moved right and up in the image (default 0 0)")
    group.add_argument("--intensity", type=float, metavar="I0",
                       help="write I0 exp(-line integral) instead of the line integral (16-bit .png and .tif: "
                            "rounded, clipped to 0..65535)")


def problem(options, input_path, output_path):
    """What is wrong with the C-arm options of a render (cli names, as argparse or a job file gives them) of
    `input_path` to `output_path`; None when nothing is."""
    def given(name):
        return options.get(name) is not None

    if not given("cone_beam"):
        extra = [name for name in OPTIONS if given(name)]
        return f"--{extra[0].replace('_', '-')} needs --cone-beam SAD SID" if extra else None
    cone = _numbers(options["cone_beam"], 2)
    if cone is None:
        return "--cone-beam needs SAD and SID, two finite numbers"
    sad, sid = cone
    if not 0 < sad < sid:
        return f"--cone-beam: the source to detector distance SID ({sid:g}) must exceed SAD ({sad:g}) > 0"
    if input_path.lower().endswith(".blend"):
        return "--cone-beam places a C-arm about a .vdb or a scan; a .blend renders with its own camera"
    if str(options.get("mode") or "XRAY").upper() != 'XRAY':
        return "--cone-beam renders DRRs: X-ray mode only"
    framing = [name for name in FRAMING_OPTIONS if given(name)]
    if framing:
        return f"--{framing[0].replace('_', '-')} frames an orthographic camera; --cone-beam places a C-arm"
    for name, count in (("pixel_spacing", 2), ("isocentre", 3), ("detector_offset", 2), ("gantry", 1),
                        ("tilt", 1), ("intensity", 1)):
        if given(name):
            values = _numbers(options[name], count)
            if values is None:
                return f"--{name.replace('_', '-')} needs {count} finite number{'s' * (count > 1)}"
            if name in ("pixel_spacing", "intensity") and min(values) <= 0:
                return f"--{name.replace('_', '-')} must be positive"
    extension = os.path.splitext(output_path)[1].lower()
    if not given("intensity") and image_io.FORMATS.get(extension) == "uint8":
        return f"'{output_path}': line integrals need a float image (.exr or .tif), or --intensity I0"
    return None


def _numbers(values, count):
    """`values` (one number, or a list of them) as a list of `count` finite numbers, or None."""
    values = list(values) if isinstance(values, (list, tuple)) else [values]
    if len(values) != count or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in values):
        return None
    return values


def c_arm_view(scene, options, gantry=None):
    """Make the scene camera the C-arm of `options` (cli names), at `gantry` degrees when given, in a scene of one
    millimetre a unit. RuntimeError with the operator's report when it cannot."""
    scene.unit_settings.scale_length = 0.001
    sad, sid = options["cone_beam"]
    properties = dict(sad=sad, sid=sid)
    if options.get("detector") is not None:
        properties["detector_cols"], properties["detector_rows"] = options["detector"]
    for name in ("pixel_spacing", "tilt", "detector_offset", "isocentre"):
        if options.get(name) is not None:
            properties[name] = options[name]
    properties["use_isocentre"] = options.get("isocentre") is not None
    gantry = options.get("gantry") if gantry is None else gantry
    if gantry is not None:
        properties["gantry"] = gantry
    volumes = [obj for obj in scene.objects if obj.type == 'VOLUME']
    if volumes:
        bpy.context.view_layer.objects.active = volumes[0]
    bpy.ops.pcvr.c_arm_view(**properties)

