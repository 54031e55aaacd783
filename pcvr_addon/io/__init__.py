# SPDX-License-Identifier: GPL-3.0-or-later

"""Files: images written and read through Blender's OpenImageIO (image_io.py), and File > Import of a scan as a
volume object (import_volume.py; the readers and the .vdb writing are in volume_import/).

(Named io on purpose: inside the package it is pcvr_addon.io, and the standard library's io, imported by
absolute name and loaded before any add-on, is never shadowed.)"""
