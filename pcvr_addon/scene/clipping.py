# SPDX-License-Identifier: GPL-3.0-or-later

"""Clipping: the part of each volume a render keeps, read from Blender as plain numbers.

A volume's settings (volume.pcvr) name a crop object, whose local [-1, 1]^3 is kept (Blender's default cube; an
empty displayed as a cube draws exactly that box), and clip-plane objects, each keeping its local +Z side.
pcvr_native takes them in world space: the crop as its world-to-box matrix (`clip_box`), each plane as (a, b, c, d)
keeping a x + b y + c z + d >= 0 (`clip_planes`); all of them intersect.

A volume whose clipping cannot be worked out (its crop or a plane object deleted, scaled to zero on an axis, or
with a matrix that is not finite) is not rendered: ClipError names the object and the cause, and the render
reports it as it reports a volume it cannot read. Rendering it uncut instead would show what the user meant to
cut away.
"""

from dataclasses import dataclass

import numpy as np


class ClipError(ValueError):
    """A crop or clip-plane object that cannot clip; the message names it."""


@dataclass(frozen=True)
class Clipping:
    """What of one volume a render keeps; compares by content (the viewport renders again when it changes)."""
    box: tuple | None = None   # world-to-box matrix, 4 rows of 4; None: no crop
    planes: tuple = ()         # (a, b, c, d) per plane, (a, b, c) of unit length

    def __bool__(self):
        return self.box is not None or bool(self.planes)

    def native_arguments(self):
        """The clip keywords of a native render of this volume's grid alone."""
        return native_arguments([self], per_grid=False)


def native_arguments(clippings, per_grid=True):
    """The clip keywords of a native render of grids clipped by `clippings` (a Clipping per grid): per-grid lists
    (or, with `per_grid` false and one Clipping, its own values), and none that no grid uses, so that an uncut
    render calls pcvr_native as it always did."""
    arguments = {}
    if any(clipping.planes for clipping in clippings):
        planes = [[list(plane) for plane in clipping.planes] or None for clipping in clippings]
        arguments["clip_planes"] = planes if per_grid else planes[0]
    if any(clipping.box is not None for clipping in clippings):
        boxes = [None if clipping.box is None else np.array(clipping.box) for clipping in clippings]
        arguments["clip_box"] = boxes if per_grid else boxes[0]
    return arguments


def _deleted(obj):
    """Whether `obj` (evaluated or not) was deleted: Blender keeps an object that a property still points to,
    but in no collection."""
    return not obj.original.users_collection


def world_to_local(obj, role):
    """The inverse of the world matrix of `obj`, the volume's `role` ("crop object", "clip plane"), checked:
    ClipError for a deleted object, one that is not finite, or one scaled to zero on an axis (whose box or
    side is empty or undefined)."""
    if obj is None:
        raise ClipError(f"a {role} is missing (none chosen, or deleted)")
    if _deleted(obj):
        raise ClipError(f"{role} '{obj.name}' was deleted (it is in no collection)")
    matrix = np.array(obj.matrix_world, dtype=np.float64)
    if not np.isfinite(matrix).all():
        raise ClipError(f"{role} '{obj.name}': its world matrix holds numbers that are not finite")
    with np.errstate(all="ignore"):
        inverse = np.linalg.inv(matrix) if np.linalg.det(matrix[:3, :3]) != 0 else None
    if inverse is None or not np.isfinite(inverse).all():
        raise ClipError(f"{role} '{obj.name}' is scaled to zero on an axis: it has no inside")
    return inverse


def crop_box(obj):
    """The world-to-box matrix of a crop object: its local [-1, 1]^3 kept."""
    return world_to_local(obj, "crop object")


def clip_plane(obj):
    """(a, b, c, d) of a clip-plane object, (a, b, c) of unit length: its local +Z side kept, z_local >= 0."""
    row = world_to_local(obj, "clip plane")[2]  # z_local as a function of world position
    return tuple(float(value) for value in row / np.linalg.norm(row[:3]))


def volume_clipping(settings):
    """The Clipping of a volume's PCVR settings (of the evaluated volume, whose objects are evaluated).
    Raises ClipError naming the crop or plane object and the cause."""
    box = None
    if settings.use_crop:
        box = tuple(tuple(float(value) for value in row) for row in crop_box(settings.crop_object))
    planes = tuple(clip_plane(item.object) for item in settings.clip_planes if item.enabled)
    return Clipping(box, planes)


def add_empty(collection, name, display_type, size=1.0, parent=None):
    """A new empty in `collection`, drawn as `display_type`, child of `parent` (then placed in its space): what
    a crop box ('CUBE' of size 1 draws the box it keeps) or a clip plane ('SINGLE_ARROW' points to the side it
    keeps) is made of."""
    import bpy

    empty = bpy.data.objects.new(name, None)
    empty.empty_display_type, empty.empty_display_size = display_type, size
    collection.objects.link(empty)
    empty.parent = parent
    return empty
