# SPDX-License-Identifier: GPL-3.0-or-later

"""Command line: render a .vdb or a .blend with the PCVR engine, without Blender's interface.

    python -m pcvr_addon render INPUT -o OUTPUT [options]

A .vdb is placed in an empty scene and framed from above (or from --view, one of Blender's numpad views, or
along --view-direction) by an orthographic camera at --magnification pixels per voxel (a numbered .vdb
brings its siblings along as a sequence, and --frame N picks file N), lit by a sun along --light-direction
and Blender's default grey world;
a .blend renders with its own camera, lights and settings, overridden by the options given.
--preset applies a transfer-function preset to every volume, --hounsfield makes the X-ray of a CT in
Hounsfield units a DRR (it integrates the linear attenuation; the default for a .vdb whose grid says its units are
HU, --no-hounsfield integrates them as they are), --clip-box and --clip-plane cut every volume
open. The image is read back from Blender's render result (after compositing) and written with OpenImageIO:
.exr holds R, G, B, A, in shaded mode the Depth pass as Z, and the raw XRay integral; .png and .tif the
Combined pass.
"""

import argparse
import os
import sys

import bpy

from .. import register, unregister
from ..batch import run as batch_run
from ..io import image_io
from ..render import statistics
from ..scene import camera
from . import command_scene, convert_command, drr
from .command_scene import (DEFAULT_LIGHT_DIRECTION, DEFAULT_MAGNIFICATION, METHODS, MODES, PASSBANDS, POST_FILTERS,
                            SPLAT_KERNELS)

DEFAULT_MU_WATER = 0.193  # per centimetre: water near 70 keV


def _resolution(text):
    try:
        width, height = (int(value) for value in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not WIDTHxHEIGHT, e.g. 640x480")
    if width < 1 or height < 1:
        raise argparse.ArgumentTypeError(f"'{text}': width and height must be positive")
    return width, height


def _gain(text):
    if text.lower() == "auto":
        return "auto"
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a number or 'auto'") from None


def make_parser():
    parser = argparse.ArgumentParser(prog="python -m pcvr_addon", description=__doc__.split("\n\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    render = commands.add_parser(
        "render", help="Render a .vdb or .blend to an image",
        description="Render a .vdb (framed from above) or a .blend (its own camera) to .exr, .png or .tif.")
    render.add_argument("input", metavar="INPUT", help="a .vdb or .blend file, or a scan (see convert)")
    render.add_argument("-o", "--output", metavar="OUTPUT", required=True,
                        help="the image to write: " + ", ".join(image_io.FORMATS))
    render.add_argument("--mode", type=str.upper, choices=MODES, help="what the image shows")
    render.add_argument("--preset", metavar="NAME",
                        help="transfer-function preset for every volume, e.g. 'CT Bone' (shaded and mip)")
    render.add_argument("--method", choices=METHODS, help="splatting algorithm")
    render.add_argument("--splat-kernel", choices=SPLAT_KERNELS, help="reconstruction kernel of a voxel")
    render.add_argument("--post-filter", choices=POST_FILTERS,
                        help="filter from the subgrid to the image (of the chosen mode)")
    render.add_argument("--stride", type=int, help="subgrid stride in pixels, 0 = automatic")
    render.add_argument("--passband", choices=PASSBANDS,
                        help="X-ray: 'compensated' pays back the blur of kernel and post filter, 'paper' does not")
    render.add_argument("--sheet-spacing", type=float, help="shaded and mip: voxels between sheets")
    render.add_argument("--samples-per-sheet", type=int, help="shaded: classified samples from sheet to sheet")
    render.add_argument("--opacity-cutoff", type=float, help="shaded: opacity at which a pixel is done")
    render.add_argument("--sheet-fill", choices=("auto", "splat", "sample"),
                        help="shaded, pcvr: splat the volume into the sheets or sample it (default auto: sampled "
                             "where footprints cover a few pixels)")
    render.add_argument("--shadows", action=argparse.BooleanOptionalAction,
                        help="shaded: the volumes shadow the light on its way to each sample (default: off for a "
                             ".vdb, the scene's setting for a .blend)")
    render.add_argument("--gain", type=_gain, metavar="GAIN|auto",
                        help="X-ray gain of the Combined pass; 'auto' picks it per image (its brightest percent "
                             "at 80%% grey)")
    render.add_argument("--stream-above", type=int, metavar="MIB",
                        help="X-ray: read volumes of more MiB than this from their files a part at a time "
                             "(default: above a quarter of the memory available)")
    render.add_argument("--frame", type=int,
                        help="frame to render; for a numbered .vdb, the number of the file (default: INPUT's)")
    render.add_argument("--magnification", type=float,
                        help=f".vdb only: pixels per voxel (default {DEFAULT_MAGNIFICATION:g})")
    render.add_argument("--grid", help=".vdb only: grid to render (default 'density', or the first float grid)")
    render.add_argument("--light-direction", type=float, nargs=3, metavar=("X", "Y", "Z"),
                        help=".vdb only: direction the sun's light travels, world space (default "
                             f"{' '.join(map(str, DEFAULT_LIGHT_DIRECTION))}; the camera looks down -Z)")
    render.add_argument("--resolution", type=_resolution, metavar="WxH",
                        help=".blend only: image size in pixels")
    render.add_argument("--view", type=str.upper, choices=list(camera.AXIS_VIEWS),
                        help=".vdb only: where the camera looks from, as Blender's numpad views (default top, "
                             "looking down -Z)")
    render.add_argument("--view-direction", type=float, nargs=3, metavar=("X", "Y", "Z"),
                        help=".vdb only: the direction the camera looks along, world space")
    render.add_argument("--hounsfield", type=float, nargs="?", const=DEFAULT_MU_WATER, metavar="MU_WATER",
                        help="X-ray of a CT in Hounsfield units: integrate mu = MU_WATER (1 + HU / 1000), never "
                             f"below 0; MU_WATER per centimetre (default {DEFAULT_MU_WATER}, water near 70 keV). "
                             "The default for a .vdb whose grid's metadata says pcvr_units = HU (what convert writes "
                             "for a CT, and a scan's INPUT)")
    render.add_argument("--no-hounsfield", dest="hounsfield", action="store_const", const=False,
                        help="integrate the grid's values as they are, Hounsfield units too (raw densities)")
    render.add_argument("--clip-box", type=float, nargs=6, metavar=("CX", "CY", "CZ", "HX", "HY", "HZ"),
                        help="keep only the part of every volume inside the box centred at CX CY CZ with half-sizes "
                             "HX HY HZ (world units; a .blend's volumes keep their own crops too)")
    render.add_argument("--clip-plane", type=float, nargs=4, action="append", metavar=("A", "B", "C", "D"),
                        help="keep only the part of every volume where A x + B y + C z + D >= 0 (world space); "
                             "repeat for more planes")
    drr.add_arguments(render, _resolution)
    convert_command.add_scan_options(render)
    convert_command.add_parser(commands)
    batch_run.add_arguments(render)
    return parser


def main(argv=None):
    parser = make_parser()
    args = parser.parse_args(argv)
    if args.command == "convert":
        return convert_command.main(args)
    # A scan renders from its .vdb, in a batch too (a job file names its own inputs).
    if not args.input.lower().endswith(".json") and convert_command.render_input(args):
        return 1
    if batch_run.wants_batch(args):
        return batch_run.run(args, parser)

    extension = os.path.splitext(args.input)[1].lower()
    if extension not in {".vdb", ".blend"}:
        parser.error(f"INPUT must be a .vdb or .blend file, not '{args.input}'")
    if not os.path.isfile(args.input):
        parser.error(f"'{args.input}' does not exist")
    if os.path.splitext(args.output)[1].lower() not in image_io.FORMATS:
        parser.error(f"OUTPUT must end in one of {', '.join(image_io.FORMATS)}")
    vdb_only = (args.magnification, args.grid, args.light_direction, args.view, args.view_direction)
    if extension == ".blend" and vdb_only != (None,) * len(vdb_only):
        parser.error("--magnification, --grid, --light-direction, --view and --view-direction apply to a .vdb; "
                     "a .blend renders with its own camera and lights")
    if args.view is not None and args.view_direction is not None:
        parser.error("--view and --view-direction both say where the camera looks: give one")
    if args.view_direction is not None and not any(args.view_direction):
        parser.error("--view-direction needs a direction, not 0 0 0")
    if args.hounsfield is not None and args.hounsfield is not False and not args.hounsfield > 0:  # 0.0 == False
        parser.error(f"--hounsfield: the attenuation of water must be positive, not {args.hounsfield}")
    if extension == ".vdb" and args.resolution is not None:
        parser.error("--resolution applies to a .blend; a .vdb is sized by --magnification")
    if args.light_direction is not None and not any(args.light_direction):
        parser.error("--light-direction needs a direction, not 0 0 0")
    command_scene.check_preset(parser, args.preset)
    problem = (command_scene.clipping_problem(args.clip_box, args.clip_plane)
               or drr.problem(vars(args), args.input, args.output))
    if problem:
        parser.error(problem)
    if not command_scene.can_write_images():
        return 1

    return render(args)


def render(args):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    register()
    try:
        if args.input.lower().endswith(".blend"):
            bpy.ops.wm.open_mainfile(filepath=os.path.abspath(args.input), load_ui=False)
        scene = bpy.context.scene
        if args.input.lower().endswith(".vdb"):
            try:
                command_scene.vdb_scene(scene, os.path.abspath(args.input), grid=args.grid, frame=args.frame,
                          magnification=args.magnification or DEFAULT_MAGNIFICATION,
                          light_direction=args.light_direction or DEFAULT_LIGHT_DIRECTION,
                          view=args.view, view_direction=args.view_direction)
            except RuntimeError as ex:
                print(f"pcvr: {ex}", file=sys.stderr)
                return 1
        command_scene.apply_options(scene, args)
        if args.cone_beam is not None:
            try:
                drr.c_arm_view(scene, vars(args))
            except RuntimeError as ex:
                print(f"pcvr: {ex}", file=sys.stderr)
                return 1

        status = 0
        try:
            bpy.ops.render.render(write_still=False)
        except RuntimeError as ex:
            # Blender's reports name every volume that could not be read; the others did render.
            print(f"pcvr: {ex}", file=sys.stderr)
            status = 1
        try:
            _write_output(scene, bpy.context.view_layer, args)
        except RuntimeError as ex:
            print(f"pcvr: nothing to write: {ex}", file=sys.stderr)
            return 1
        last = statistics.last_render.get(scene.session_uid)
        if last is not None:
            print(f"pcvr: {statistics.status_line(*last)}")
        print(f"pcvr: wrote {args.output}")
        return status
    finally:
        unregister()


def _write_output(scene, view_layer, args):
    passes = image_io.render_result_passes(scene)
    if args.cone_beam is not None:
        image_io.write_drr(args.output, passes[f"{view_layer.name}.XRay"][:, :, 0], args.intensity)
        return
    filepath = args.output
    combined = passes.get("Composite.Combined", passes[f"{view_layer.name}.Combined"])
    extra = {name: passes[f"{view_layer.name}.{name}"] for name in ("Depth", "XRay")
             if f"{view_layer.name}.{name}" in passes}
    image_io.write_passes(filepath, {"Combined": combined, **extra})
