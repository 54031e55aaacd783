# SPDX-License-Identifier: GPL-3.0-or-later

"""The scene a command line renders, for `python -m pcvr_addon render` (main.py) and its batches (batch/): a .vdb
imported, framed and lit, and the command line's options applied to a scene. Below both, so neither imports the
other."""

import math
import os
import re
import sys

import bpy
from mathutils import Matrix, Vector

from ..io import image_io
from ..render import prepared_scene
from ..scene import clipping
from ..scene.defaults import NATIVE_NAMES
from ..ui import presets
from ..ui.properties import (enum_methods, enum_modes, enum_passbands, enum_post_filters, enum_sheet_fills,
                             enum_splat_kernels)
from ..volume_import import SCAN_WORLD

DEFAULT_MAGNIFICATION = 4.0
# The sun of a .vdb: from the upper left and in front, as seen by the camera above it; strength pi W/m^2 shows
# a white surface facing it as white, as in Cycles (see scene/lighting.py).
DEFAULT_LIGHT_DIRECTION = (0.4, -0.4, -0.8)
SUN_STRENGTH = math.pi
# Blender's default world colour, the ambient light and background of a .vdb.
WORLD_COLOUR = (0.05, 0.05, 0.05)


def _native_choices(items):
    return {NATIVE_NAMES[identifier]: identifier for identifier, _name, _description in items}


METHODS = _native_choices(enum_methods)
SPLAT_KERNELS = _native_choices(enum_splat_kernels)
POST_FILTERS = _native_choices(enum_post_filters)
PASSBANDS = _native_choices(enum_passbands)
SHEET_FILLS = _native_choices(enum_sheet_fills)
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
    world; a grid whose metadata says its units are HU (a CT) X-rayed as a DRR (xray_values 'HOUNSFIELD'), and one
    that convert placed in millimetres in a scene of one millimetre a unit. Returns
    the volume object; raises RuntimeError with the operator's report when the volume cannot be read."""
    obj, file_frame = _import_vdb(filepath)
    if grid:
        obj.data.pcvr.grid = grid
    metadata = grid_metadata(filepath, grid)
    if metadata.get("pcvr_units") == "HU":
        # A CT's X-ray is a DRR unless --no-hounsfield says otherwise (apply_options).
        obj.data.pcvr.xray_values = 'HOUNSFIELD'
    if metadata.get("pcvr_world") == SCAN_WORLD:
        # A converted scan: one unit a millimetre, so that a DRR's attenuation per centimetre counts it so (the
        # default metre made a head 200 m deep, its DRR white).
        scene.unit_settings.scale_length = 0.001
    frame = frame if frame is not None else file_frame
    if frame is not None:
        scene.frame_set(frame)
    if view_direction is not None:
        bpy.ops.pcvr.frame_volume(magnification=magnification, view='DIRECTION', direction=view_direction,
                                  set_resolution=True)
    else:
        bpy.ops.pcvr.frame_volume(magnification=magnification, view=view or 'TOP', set_resolution=True)
    _light(scene, light_direction)
    return obj


def grid_metadata(filepath, grid=None):
    """The string metadata of the grid `grid` of the .vdb `filepath` (None: 'density', else the first): what convert
    wrote of a scan among them (`pcvr_units`, "HU" for a CT; `pcvr_world`); {} where the file does not say."""
    try:
        entry = prepared_scene.grid_entry(filepath, grid)
    except (OSError, RuntimeError, ValueError):
        return {}
    return entry.get("metadata", {}) if entry else {}


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


# Options that set one scene setting: (option, setting, the setting's value by the option's, or None: as given).
SCENE_OPTIONS = (
    ("method", "method", METHODS), ("splat_kernel", "splat_kernel", SPLAT_KERNELS), ("stride", "subgrid_stride", None),
    ("passband", "passband", PASSBANDS), ("sheet_fill", "sheet_fill", SHEET_FILLS),
    ("sheet_spacing", "sheet_spacing", None), ("samples_per_sheet", "samples_per_sheet", None),
    ("opacity_cutoff", "opacity_cutoff", None), ("stream_above", "stream_above", None), ("shadows", "shadows", None),
)


def apply_options(scene, args):
    scene.render.engine = 'PCVR'
    settings = scene.pcvr
    if args.mode is not None:
        settings.mode = args.mode
    for option, setting, values in SCENE_OPTIONS:
        value = getattr(args, option)
        if value is not None:
            setattr(settings, setting, value if values is None else values[value])
    if args.post_filter is not None:
        setattr(settings, "post_filter" if settings.mode == 'XRAY' else "sheet_post_filter",
                POST_FILTERS[args.post_filter])
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
    if args.hounsfield is False:  # --no-hounsfield
        for volume in bpy.data.volumes:
            volume.pcvr.xray_values = 'DENSITY'
    elif args.hounsfield is not None:
        for volume in bpy.data.volumes:
            volume.pcvr.xray_values, volume.pcvr.mu_water = 'HOUNSFIELD', args.hounsfield
    if args.clip_box is not None or args.clip_plane:
        add_clipping(scene, args.clip_box, args.clip_plane or ())
    for view_layer in scene.view_layers:
        view_layer.pcvr.use_pass_xray = True
        view_layer.use_pass_z = settings.mode == 'SHADED'


def clipping_problem(clip_box, clip_planes):
    """What is wrong with the command line's --clip-box (CX CY CZ HX HY HZ) and --clip-plane (A B C D, a list
    of them), as they come from argparse or a job file's options; None when nothing is."""
    def numbers(values, count):
        return (isinstance(values, (list, tuple)) and len(values) == count
                and all(isinstance(value, (int, float)) and math.isfinite(value) for value in values))

    if clip_box is not None:
        if not numbers(clip_box, 6):
            return f"--clip-box needs 6 finite numbers (centre X Y Z, half-sizes X Y Z), not {clip_box}"
        if min(clip_box[3:]) <= 0:
            return f"--clip-box: the half-sizes must be positive, not {' '.join(map(str, clip_box[3:]))}"
    for plane in clip_planes or ():
        if not numbers(plane, 4):
            return f"--clip-plane needs 4 finite numbers (A B C D: keep A x + B y + C z + D >= 0), not {plane}"
        if not any(plane[:3]):
            return "--clip-plane needs a normal: A, B and C cannot all be 0"
    return None


def add_clipping(scene, clip_box=None, clip_planes=()):
    """Cut every volume to the box `clip_box` (centre X Y Z and half-sizes X Y Z, world units) and to each plane
    (A, B, C, D) of `clip_planes` (keeping A x + B y + C z + D >= 0), besides its own crop and clip planes: as
    empties in `scene`, a user of the saved .blend would see them. A volume with a crop object of its own keeps
    it, and the box is cut by six planes on its faces."""
    volumes = list(bpy.data.volumes)
    for plane in clip_planes:
        normal = Vector(plane[:3])
        empty = clipping.add_empty(scene.collection, "Command-Line Clip Plane", 'SINGLE_ARROW')
        # Through the point of the plane nearest the origin, its local Z along the normal.
        empty.matrix_world = Matrix.LocRotScale(-plane[3] / normal.length_squared * normal,
                                                normal.to_track_quat('Z', 'Y'), None)
        for volume in volumes:
            volume.pcvr.clip_planes.add().object = empty
    if clip_box is None:
        return
    box = clipping.add_empty(scene.collection, "Command-Line Clip Box", 'CUBE')
    box.matrix_world = Matrix.LocRotScale(Vector(clip_box[:3]), None, Vector(clip_box[3:]))
    faces = None
    for volume in volumes:
        settings = volume.pcvr
        if not settings.use_crop:
            settings.crop_object, settings.use_crop = box, True
            continue
        faces = faces or _box_faces(scene, box)
        for face in faces:
            settings.clip_planes.add().object = face


def _box_faces(scene, box):
    """Six plane empties, children of the crop object `box`, on the faces of its box, each keeping its inside."""
    faces = []
    for axis in range(3):
        for side in (-1.0, 1.0):
            inwards = Vector([-side if i == axis else 0.0 for i in range(3)])
            face = clipping.add_empty(scene.collection, f"{box.name} {'-+'[side > 0]}{'XYZ'[axis]}", 'SINGLE_ARROW',
                                      size=0.5, parent=box)
            # On the face at box coordinate `side` along `axis`, its local Z pointing into the box.
            face.matrix_basis = Matrix.LocRotScale(-inwards, inwards.to_track_quat('Z', 'Y'), None)
            faces.append(face)
    return faces
