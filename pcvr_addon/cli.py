# SPDX-License-Identifier: GPL-3.0-or-later

"""Command line: render a .vdb or a .blend with the PCVR engine, without Blender's interface.

    python -m pcvr_addon render INPUT -o OUTPUT [options]

A .vdb is placed in an empty scene and framed from above (or from --view, one of Blender's numpad views, or
along --view-direction) by an orthographic camera at --magnification pixels per voxel (a numbered .vdb
brings its siblings along as a sequence, and --frame N picks file N), lit by a sun along --light-direction
and Blender's default grey world;
a .blend renders with its own camera, lights and settings, overridden by the options given.
--preset applies a transfer-function preset to every volume, --hounsfield makes the X-ray of a CT in
Hounsfield units a DRR (it integrates the linear attenuation). The image is read back from
Blender's render result (after compositing) and written with OpenImageIO: .exr holds R, G, B, A,
in shaded mode the Depth pass as Z, and the raw XRay integral; .png and .tif the Combined pass.
"""

import argparse
import math
import os
import re
import sys

import bpy
from mathutils import Vector

from . import camera, convert_command, image_io, presets, register, statistics, unregister
from .batch import run as batch_run
from .properties import NATIVE_NAMES, enum_methods, enum_modes, enum_post_filters, enum_splat_kernels

DEFAULT_MAGNIFICATION = 4.0
DEFAULT_MU_WATER = 0.193  # per centimetre: water near 70 keV
# The sun of a .vdb: from the upper left and in front, as seen by the camera above it; strength pi W/m^2 shows
# a white surface facing it as white, as in Cycles (see lighting.py).
DEFAULT_LIGHT_DIRECTION = (0.4, -0.4, -0.8)
SUN_STRENGTH = math.pi
# Blender's default world colour, the ambient light and background of a .vdb.
WORLD_COLOUR = (0.05, 0.05, 0.05)


def _native_choices(items):
    return {NATIVE_NAMES[identifier]: identifier for identifier, _name, _description in items}


METHODS = _native_choices(enum_methods)
SPLAT_KERNELS = _native_choices(enum_splat_kernels)
POST_FILTERS = _native_choices(enum_post_filters)
MODES = [identifier for identifier, _name, _description in enum_modes]


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
    render.add_argument("--sheet-spacing", type=float, help="shaded and mip: voxels between sheets")
    render.add_argument("--samples-per-sheet", type=int, help="shaded: classified samples from sheet to sheet")
    render.add_argument("--opacity-cutoff", type=float, help="shaded: opacity at which a pixel is done")
    render.add_argument("--gain", type=_gain, metavar="GAIN|auto",
                        help="X-ray gain of the Combined pass; 'auto' picks it per image (its brightest percent "
                             "at 95%% grey)")
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
                             f"below 0; MU_WATER per centimetre (default {DEFAULT_MU_WATER}, water near 70 keV)")
    convert_command.add_scan_options(render)
    convert_command.add_parser(commands)
    batch_run.add_arguments(render)
    return parser


def main(argv=None):
    parser = make_parser()
    args = parser.parse_args(argv)
    if args.command == "convert":
        return convert_command.main(args)
    if batch_run.wants_batch(args):
        return batch_run.run(args, parser)
    if convert_command.render_input(args):  # a scan: rendered from its .vdb
        return 1

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
    if args.hounsfield is not None and not args.hounsfield > 0:
        parser.error(f"--hounsfield: the attenuation of water must be positive, not {args.hounsfield}")
    if extension == ".vdb" and args.resolution is not None:
        parser.error("--resolution applies to a .blend; a .vdb is sized by --magnification")
    if args.light_direction is not None and not any(args.light_direction):
        parser.error("--light-direction needs a direction, not 0 0 0")
    if args.preset is not None:
        try:
            presets.find(args.preset)
        except KeyError as ex:
            parser.error(ex.args[0])
    try:
        image_io.openimageio()  # before rendering, not after
    except ImportError as ex:
        print(f"pcvr: {ex}", file=sys.stderr)
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
                vdb_scene(scene, os.path.abspath(args.input), grid=args.grid, frame=args.frame,
                          magnification=args.magnification or DEFAULT_MAGNIFICATION,
                          light_direction=args.light_direction or DEFAULT_LIGHT_DIRECTION,
                          view=args.view, view_direction=args.view_direction)
            except RuntimeError as ex:
                print(f"pcvr: {ex}", file=sys.stderr)
                return 1
        _apply_options(scene, args)

        status = 0
        try:
            bpy.ops.render.render(write_still=False)
        except RuntimeError as ex:
            # Blender's reports name every volume that could not be read; the others did render.
            print(f"pcvr: {ex}", file=sys.stderr)
            status = 1
        try:
            _write_output(scene, bpy.context.view_layer, args.output)
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


def vdb_scene(scene, filepath, grid=None, frame=None, magnification=DEFAULT_MAGNIFICATION,
              light_direction=DEFAULT_LIGHT_DIRECTION, view=None, view_direction=None):
    """Make `scene` (empty) show the .vdb `filepath` as the command line renders it: imported (grid `grid`, at
    frame `frame` or the file's number), framed at `magnification` from `view` (a camera.AXIS_VIEWS key; default
    from above) or along `view_direction`, lit by a sun travelling along `light_direction` and Blender's default
    world. Returns the volume object; raises RuntimeError with the operator's report when the volume cannot be
    read."""
    obj, file_frame = _import_vdb(filepath)
    if grid:
        obj.data.pcvr.grid = grid
    frame = frame if frame is not None else file_frame
    if frame is not None:
        scene.frame_set(frame)
    if view_direction is not None:
        bpy.ops.pcvr.frame_volume(magnification=magnification, view='DIRECTION', direction=view_direction)
    else:
        bpy.ops.pcvr.frame_volume(magnification=magnification, view=view or 'TOP')
    _light(scene, light_direction)
    return obj


def _light(scene, direction):
    """A sun whose light travels along `direction`, and Blender's default world."""
    sun = bpy.data.lights.new("Sun", 'SUN')
    sun.energy = SUN_STRENGTH
    obj = bpy.data.objects.new("Sun", sun)
    # A sun shines along its local -Z axis.
    obj.rotation_euler = (-Vector(direction)).to_track_quat('Z', 'Y').to_euler()
    scene.collection.objects.link(obj)
    scene.world = bpy.data.worlds.new("World")
    scene.world.color = WORLD_COLOUR
    if scene.world.node_tree is not None:  # 5.0 gives a new world nodes, which it renders
        scene.world.node_tree.nodes["Background"].inputs["Color"].default_value = (*WORLD_COLOUR, 1.0)


def _import_vdb(filepath):
    """Import a .vdb as File > Import > OpenVDB does. A numbered file (smoke_0007.vdb) brings its
    numbered siblings along as a sequence in which frame N shows file N. Returns the new object and
    the input file's number (None when it has none)."""
    directory, name = os.path.split(filepath)
    numbered = re.fullmatch(r"(.*?)(\d+)(\.vdb)", name, re.IGNORECASE)
    files = [name]
    if numbered:
        prefix, digits, extension = numbered.groups()
        sibling = re.compile(re.escape(prefix) + r"\d{%d}" % len(digits) + re.escape(extension), re.IGNORECASE)
        files = sorted(entry for entry in os.listdir(directory) if sibling.fullmatch(entry))
    imported = bpy.ops.object.volume_import(filepath=filepath, directory=directory,
                                            files=[{"name": f} for f in files],
                                            use_sequence_detection=True, relative_path=False)
    if 'FINISHED' not in imported:
        raise RuntimeError(f"'{filepath}' is not a readable OpenVDB file")
    obj = bpy.context.view_layer.objects.active
    volume = obj.data
    if volume.is_sequence:
        # Blender starts the sequence at frame 1 and offsets the file numbers; start it at the
        # first file's number instead.
        volume.frame_start = volume.frame_offset + 1
    return obj, int(numbered.group(2)) if numbered else None


def _apply_options(scene, args):
    scene.render.engine = 'PCVR'
    settings = scene.pcvr
    if args.mode is not None:
        settings.mode = args.mode
    if args.method is not None:
        settings.method = METHODS[args.method]
    if args.splat_kernel is not None:
        settings.splat_kernel = SPLAT_KERNELS[args.splat_kernel]
    if args.post_filter is not None:
        setattr(settings, "post_filter" if settings.mode == 'XRAY' else "sheet_post_filter",
                POST_FILTERS[args.post_filter])
    for option in ("sheet_spacing", "samples_per_sheet", "opacity_cutoff", "stream_above"):
        if getattr(args, option) is not None:
            setattr(settings, option, getattr(args, option))
    if args.stride is not None:
        settings.subgrid_stride = args.stride
    if args.gain == "auto":
        settings.use_auto_exposure = True
    elif args.gain is not None:
        settings.xray_gain = args.gain
    if args.resolution is not None:
        scene.render.resolution_x, scene.render.resolution_y = args.resolution
        scene.render.resolution_percentage = 100
    if args.frame is not None and scene.frame_current != args.frame:
        scene.frame_set(args.frame)
    if args.preset is not None:
        for volume in bpy.data.volumes:
            volume.pcvr.apply_preset(args.preset)
    if args.hounsfield is not None:
        for volume in bpy.data.volumes:
            volume.pcvr.xray_values, volume.pcvr.mu_water = 'HOUNSFIELD', args.hounsfield
    for view_layer in scene.view_layers:
        view_layer.pcvr.use_pass_xray = True
        view_layer.use_pass_z = settings.mode == 'SHADED'


def _write_output(scene, view_layer, filepath):
    passes = image_io.render_result_passes(scene)
    combined = passes.get("Composite.Combined", passes[f"{view_layer.name}.Combined"])
    extra = {name: passes[f"{view_layer.name}.{name}"] for name in ("Depth", "XRay")
             if f"{view_layer.name}.{name}" in passes}
    image_io.write_passes(filepath, {"Combined": combined, **extra})
