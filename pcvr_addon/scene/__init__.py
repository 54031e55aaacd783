# SPDX-License-Identifier: GPL-3.0-or-later

"""Blender's data as the native renderer's inputs: the camera, the volumes and their grids, lights and world,
volume materials, clipping, transfer functions, and the defaults the settings share with pcvr_native.
scene_inputs.read gathers them all on Blender's main thread."""
