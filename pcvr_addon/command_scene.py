# SPDX-License-Identifier: GPL-3.0-or-later

"""The scene a command line renders, for `python -m pcvr_addon render` (cli.py) and its batches (batch/): a .vdb
imported, framed and lit, and the command line's options applied to a scene. Below both, so neither imports the
other."""

import math
import os
import re
import sys

import bpy
from mathutils import Vector

from . import image_io, presets
from .properties import NATIVE_NAMES, enum_methods, enum_modes, enum_post_filters, enum_splat_kernels

DEFAULT_MAGNIFICATION = 4.0
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


def check_preset(parser, name):
    """parser.error listing the presets there are, unless `name` is one of them (or None)."""
    if name is not None:
        try:
            presets.find(name)
        except KeyError as ex:
            parser.error(ex.args[0])


def can_write_images():
    """Whether OpenImageIO is there to write the images, checked before rendering rather than after; says why
    not on stderr."""
    try:
        image_io.openimageio()
    except ImportError as ex:
        print(f"pcvr: {ex}", file=sys.stderr)
        return False
    return True


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


def apply_options(scene, args):
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
