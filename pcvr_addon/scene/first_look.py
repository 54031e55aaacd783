# SPDX-License-Identifier: GPL-3.0-or-later

"""Scene settings that make a good first image of a volume, set where the user brings one in (File > Import >
PCVR Volume, Frame Volume) or switches PCVR to X-ray mode:

- an X-ray shown through the Standard view transform: Blender's default, AgX (and Filmic before it), compresses
  the highlights and lifts the blacks of what is a plain grey image, and a DRR looks washed out. Another view
  transform the user chose (Standard, Raw, False Color, ...) stays;
- a scan lit from the camera's side: Blender's default light stands behind a patient who faces its front view
  (LPS puts the patient's anterior at -Y), so shaded mode would show the back lit. One sun, the add-on's own
  (found again by its `pcvr_scan_light` property: importing again aims it, never adds another), shines along the
  camera's view and a little down; without a camera, from the front (-Y), a little above.
"""

import math

import bpy
from mathutils import Matrix, Vector

# The view transforms that change the look of a grey image; Standard shows it as it is.
TONE_MAPPING_VIEWS = {'AgX', 'Filmic'}
LIGHT_TAG = "pcvr_scan_light"
LIGHT_NAME = "PCVR Scan Light"
# pi W/m^2 shows a white surface facing the sun as white, as in Cycles (the command line's sun, scene/lighting.py).
LIGHT_STRENGTH = math.pi
# How far the light comes from above the view: tan of about 22 degrees.
LIGHT_ELEVATION = 0.4


def show_xray_plainly(scene):
    """In X-ray mode, the Standard view transform where the scene's is AgX or Filmic. Returns whether it changed."""
    settings = scene.view_settings
    if scene.pcvr.mode != 'XRAY' or settings.view_transform not in TONE_MAPPING_VIEWS:
        return False
    settings.view_transform = 'Standard'
    return True


def scan_light(scene):
    """The add-on's scan light in `scene`, or None."""
    return next((obj for obj in scene.objects if obj.get(LIGHT_TAG) and obj.type == 'LIGHT'), None)


def light_direction(scene):
    """The direction the scan light shines: the scene camera's view, tilted down by LIGHT_ELEVATION of its up;
    without a camera, towards +Y (from the front view's side), a little down."""
    if scene.camera is not None:
        matrix = scene.camera.matrix_world.to_3x3().normalized()
        forward, up = -matrix.col[2], matrix.col[1]
    else:
        forward, up = Vector((0.0, 1.0, 0.0)), Vector((0.0, 0.0, 1.0))
    return (forward - LIGHT_ELEVATION * up).normalized()


def aim_scan_light(scene, add=True):
    """Aim the scan light at what the camera sees (light_direction), adding it first (with `add`) where the scene
    has none. Returns the light object, or None."""
    obj = scan_light(scene)
    if obj is None:
        if not add:
            return None
        light = bpy.data.lights.new(LIGHT_NAME, 'SUN')
        light.energy = LIGHT_STRENGTH
        obj = bpy.data.objects.new(LIGHT_NAME, light)
        obj[LIGHT_TAG] = True
        scene.collection.objects.link(obj)
    # A sun shines along its local -Z axis.
    rotation = (-light_direction(scene)).to_track_quat('Z', 'Y')
    obj.matrix_world = Matrix.LocRotScale(obj.matrix_world.translation, rotation, None)
    return obj
