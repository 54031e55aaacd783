# SPDX-License-Identifier: GPL-3.0-or-later

"""File > Import > PCVR Volume: a DICOM series, NIfTI, NRRD, MetaImage or TIFF stack as a volume object.

The scan is converted to a .vdb (volume_import; reused while the scan is unchanged) and loaded as a Volume
whose grid holds LPS millimetres: the object's scale (Unit Scale) turns millimetres into scene units, so
the volume sits where the data says, the patient upright facing Blender's front view. With Apply Preset,
a CT gets the 'CT Bone' transfer function and an MR 'MR Default'. A scan in Hounsfield units X-rays as a DRR
(X-Ray Values: Hounsfield Units), in X-ray mode through the Standard view transform; with Add Light, one sun lights
it from the camera's side (scene/first_look.py).
"""

import os

import bpy
from bpy.props import BoolProperty, FloatProperty, IntProperty, StringProperty
from bpy.types import Operator
from bpy_extras.io_utils import ImportHelper

from .. import volume_import
from ..scene import first_look

MENU_LABEL = "PCVR Volume (DICOM, NIfTI, NRRD, MetaImage, TIFF)"
PRESET_FOR_MODALITY = {"CT": "CT Bone", "MR": "MR Default"}
# Beside a saved .blend: its converted volumes, relative to it.
BLEND_VOLUME_FOLDER = "pcvr_volumes"


def vdb_directory(explicit):
    """Where the .vdb goes: the folder the user named, else beside the saved .blend, else the user's cache."""
    if explicit:
        return bpy.path.abspath(explicit)
    if bpy.data.filepath:
        return os.path.join(os.path.dirname(bpy.data.filepath), BLEND_VOLUME_FOLDER)
    return None


def scan_path(filepath):
    """The file picked, or the folder when none was (a DICOM folder chosen by its path)."""
    return filepath if os.path.isfile(filepath) else (os.path.dirname(filepath) or filepath)


def add_volume_object(context, vdb_path, name, unit_scale):
    volume = bpy.data.volumes.new(name)
    # Relative to a saved .blend, so that the two move together.
    volume.filepath = bpy.path.relpath(vdb_path) if bpy.data.filepath else vdb_path
    obj = bpy.data.objects.new(name, volume)
    obj.scale = (unit_scale,) * 3
    context.collection.objects.link(obj)
    for other in context.view_layer.objects.selected:
        other.select_set(False)
    obj.select_set(True)
    context.view_layer.objects.active = obj
    return obj


class PCVR_OT_import_volume(Operator, ImportHelper):
    """Import a DICOM series, NIfTI, NRRD, MetaImage or TIFF stack as a volume (converted to OpenVDB)"""

    bl_idname = "pcvr.import_volume"
    bl_label = "Import PCVR Volume"
    bl_options = {'REGISTER', 'UNDO'}

    filter_glob: StringProperty(default=volume_import.FILE_PATTERNS, options={'HIDDEN'})
    unit_scale: FloatProperty(
        name="Unit Scale", description="Scene units per millimetre (0.001: metres)",
        default=0.001, min=1e-9, soft_min=1e-6, soft_max=1.0, precision=4)
    apply_preset: BoolProperty(
        name="Apply Preset", description="Give a CT the 'CT Bone' transfer function and an MR 'MR Default'",
        default=True)
    series: StringProperty(
        name="Series", description="DICOM: the series, by index or UID, when a folder holds several "
                                   "(empty: the series of the file picked)")
    frame: IntProperty(
        name="Frame", description="4-D NIfTI or TIFF time series: the volume to import (-1: the file has one)",
        default=-1, min=-1)
    add_light: BoolProperty(
        name="Add Light",
        description="Light the scan from the camera's side (from the front without a camera) with a sun, the add-on's "
                    "own: importing again aims it rather than adding another",
        default=True)
    directory_for_vdb: StringProperty(
        name="VDB Folder", subtype='DIR_PATH',
        description="Where the converted .vdb is written (empty: a 'pcvr_volumes' folder beside the saved "
                    ".blend, else the user's cache)")

    def execute(self, context):
        from ..volume_import.vdb_cache import cached_vdb

        path = scan_path(self.filepath)
        try:
            vdb_path, scan = cached_vdb(path, series=self.series or None,
                                        frame=None if self.frame < 0 else self.frame,
                                        directory=vdb_directory(self.directory_for_vdb))
        except volume_import.ScanError as ex:
            self.report({'ERROR'}, str(ex))
            return {'CANCELLED'}
        name = os.path.basename(vdb_path)[:-len("_volume.vdb")] or "Scan"
        obj = add_volume_object(context, vdb_path, name, self.unit_scale)
        for key, value in scan.metadata().items():
            obj.data[key] = value
        preset = PRESET_FOR_MODALITY.get(scan.modality)
        if self.apply_preset and preset:
            obj.data.pcvr.apply_preset(preset)
        if scan.units == "HU":
            obj.data.pcvr.xray_values = 'HOUNSFIELD'  # a DRR, not the integral of raw Hounsfield units
        if self.add_light:
            first_look.aim_scan_light(context.scene)
        first_look.show_xray_plainly(context.scene)
        self.report({'INFO'}, f"Imported {scan.description()} from {vdb_path}")
        return {'FINISHED'}


def menu_import(self, _context):
    self.layout.operator(PCVR_OT_import_volume.bl_idname, text=MENU_LABEL)


def register():
    bpy.utils.register_class(PCVR_OT_import_volume)
    bpy.types.TOPBAR_MT_file_import.append(menu_import)


def unregister():
    bpy.types.TOPBAR_MT_file_import.remove(menu_import)
    bpy.utils.unregister_class(PCVR_OT_import_volume)
