"""Crop boxes and clip planes for the add-on tests, and the world-space numbers they stand for, worked out here
by hand (not by pcvr_addon.scene.clipping) so that the tests check the add-on's reading of Blender's objects."""

import bpy
import numpy as np


def rotation_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def world_to_box(centre, half_sizes, angle_z=0.0):
    """The world-to-box matrix of a box centred at `centre`, turned by `angle_z` about Z, with `half_sizes`."""
    box_to_world = np.eye(4)
    box_to_world[:3, :3] = rotation_z(angle_z) @ np.diag(half_sizes)
    box_to_world[:3, 3] = centre
    return np.linalg.inv(box_to_world)


def add_empty(name, display_type='CUBE', location=(0.0, 0.0, 0.0), rotation=(0.0, 0.0, 0.0), scale=(1.0, 1.0, 1.0)):
    empty = bpy.data.objects.new(name, None)
    empty.empty_display_type = display_type
    empty.location, empty.rotation_euler, empty.scale = location, rotation, scale
    bpy.context.scene.collection.objects.link(empty)
    return empty


def crop(obj, crop_object):
    """Crop the volume object `obj` to `crop_object`'s box."""
    settings = obj.data.pcvr
    settings.crop_object, settings.use_crop = crop_object, True
    return crop_object


def add_clip_plane(obj, plane_object):
    obj.data.pcvr.clip_planes.add().object = plane_object
    return plane_object
