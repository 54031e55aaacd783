# SPDX-License-Identifier: GPL-3.0-or-later

"""Command line: render a .vdb or a .blend with the PCVR engine, without Blender's interface.

    python -m pcvr_addon render INPUT -o OUTPUT [options]

A .vdb is placed in an empty scene and framed from above by an orthographic camera at
--magnification pixels per voxel (a numbered .vdb brings its siblings along as a sequence, and
--frame N picks file N); a .blend renders with its own camera and settings, overridden by the
options given. The image is read back from Blender's render result (after compositing) and
written with OpenImageIO: .exr holds R, G, B, A and the raw XRay integral, .png and .tif the
Combined pass.
"""

import argparse
import os
import re
import sys

import bpy
import numpy as np

from . import image_io, register, unregister
from .properties import NATIVE_NAMES, enum_methods, enum_modes, enum_post_filters, enum_splat_kernels

DEFAULT_MAGNIFICATION = 4.0


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


def make_parser():
    parser = argparse.ArgumentParser(prog="python -m pcvr_addon", description=__doc__.split("\n\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    render = commands.add_parser(
        "render", help="Render a .vdb or .blend to an image",
        description="Render a .vdb (framed from above) or a .blend (its own camera) to .exr, .png or .tif.")
    render.add_argument("input", metavar="INPUT", help="a .vdb or .blend file")
    render.add_argument("-o", "--output", metavar="OUTPUT", required=True,
                        help="the image to write: " + ", ".join(image_io.FORMATS))
    render.add_argument("--mode", type=str.upper, choices=MODES, help="what the image shows")
    render.add_argument("--method", choices=METHODS, help="splatting algorithm")
    render.add_argument("--splat-kernel", choices=SPLAT_KERNELS, help="reconstruction kernel of a voxel")
    render.add_argument("--post-filter", choices=POST_FILTERS, help="filter from the subgrid to the image")
    render.add_argument("--stride", type=int, help="subgrid stride in pixels, 0 = automatic")
    render.add_argument("--gain", type=float, help="X-ray gain of the Combined pass")
    render.add_argument("--frame", type=int,
                        help="frame to render; for a numbered .vdb, the number of the file (default: INPUT's)")
    render.add_argument("--magnification", type=float,
                        help=f".vdb only: pixels per voxel (default {DEFAULT_MAGNIFICATION:g})")
    render.add_argument("--grid", help=".vdb only: grid to render (default 'density', or the first float grid)")
    render.add_argument("--resolution", type=_resolution, metavar="WxH",
                        help=".blend only: image size in pixels")
    return parser


def main(argv=None):
    parser = make_parser()
    args = parser.parse_args(argv)

    extension = os.path.splitext(args.input)[1].lower()
    if extension not in {".vdb", ".blend"}:
        parser.error(f"INPUT must be a .vdb or .blend file, not '{args.input}'")
    if not os.path.isfile(args.input):
        parser.error(f"'{args.input}' does not exist")
    if os.path.splitext(args.output)[1].lower() not in image_io.FORMATS:
        parser.error(f"OUTPUT must end in one of {', '.join(image_io.FORMATS)}")
    if extension == ".blend" and (args.magnification is not None or args.grid is not None):
        parser.error("--magnification and --grid apply to a .vdb; a .blend renders with its own camera")
    if extension == ".vdb" and args.resolution is not None:
        parser.error("--resolution applies to a .blend; a .vdb is sized by --magnification")
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
                _frame_vdb(scene, os.path.abspath(args.input), args)
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
        print(f"pcvr: wrote {args.output}")
        return status
    finally:
        unregister()


def _frame_vdb(scene, filepath, args):
    obj, file_frame = _import_vdb(filepath)
    if args.grid:
        obj.data.pcvr.grid = args.grid
    frame = args.frame if args.frame is not None else file_frame
    if frame is not None:
        scene.frame_set(frame)
    # Raises RuntimeError with the operator's report when the volume cannot be read.
    bpy.ops.pcvr.frame_volume(magnification=args.magnification or DEFAULT_MAGNIFICATION)


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
        settings.post_filter = POST_FILTERS[args.post_filter]
    if args.stride is not None:
        settings.subgrid_stride = args.stride
    if args.gain is not None:
        settings.xray_gain = args.gain
    if args.resolution is not None:
        scene.render.resolution_x, scene.render.resolution_y = args.resolution
        scene.render.resolution_percentage = 100
    if args.frame is not None and scene.frame_current != args.frame:
        scene.frame_set(args.frame)
    for view_layer in scene.view_layers:
        view_layer.pcvr.use_pass_xray = True


def _write_output(scene, view_layer, filepath):
    passes = image_io.render_result_passes(scene)
    combined = passes.get("Composite.Combined", passes[f"{view_layer.name}.Combined"])
    if not filepath.lower().endswith(".exr"):
        image_io.write_image(filepath, combined)
        return
    xray = passes[f"{view_layer.name}.XRay"]
    image_io.write_image(filepath, np.concatenate([combined, xray], axis=-1),
                         channel_names=["R", "G", "B", "A", "XRay"])
