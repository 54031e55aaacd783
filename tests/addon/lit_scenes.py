"""Scenes for the shaded and MIP tests: lights, a world, transfer functions, a CT-like head in Hounsfield units,
and what pcvr_native makes of the same numbers when called directly (the references)."""

import math

import bpy
import numpy as np
import pcvr_native as pn
from mathutils import Euler, Vector

import blender_scenes as bs
from tools import ct_head

# A transfer function over densities 0..1.5 (bs.blob's values reach about 1.5): transparent below 0.2, red
# turning white and opaque towards the top.
RAMP = [
    (0.0, (0.0, 0.0, 0.0, 0.0)),
    (0.2, (0.8, 0.2, 0.1, 0.0)),
    (0.6, (0.9, 0.6, 0.3, 0.5)),
    (1.0, (1.0, 1.0, 1.0, 0.9)),
]
RAMP_RANGE = (0.0, 1.5)


def shaded_setup(width=64, height=64, method='REGULAR', mode='SHADED', transparent=True):
    """bs.setup in shaded (or another) mode, the film transparent by default."""
    scene = bs.setup(width, height, method=method, xray_pass=False)
    scene.pcvr.mode = mode
    scene.render.film_transparent = transparent
    return scene


def set_ramp(obj, ramp=RAMP, tf_range=RAMP_RANGE):
    obj.data.pcvr.set_transfer_function(*tf_range, ramp)


def reference_transfer_function(voxel_size=0.1, opacity_scale=1.0, ramp=RAMP, tf_range=RAMP_RANGE):
    """pcvr_native's transfer function of `ramp` over `tf_range`, opacity per voxel of `voxel_size`."""
    low, high = tf_range
    return pn.TransferFunction(density=[low + position * (high - low) for position, _rgba in ramp],
                               rgba=[rgba for _position, rgba in ramp], unit_distance=voxel_size / opacity_scale)


def add_light(kind, location=(0.0, 0.0, 3.0), rotation=(0.0, 0.0, 0.0), power=1.0, color=(1.0, 1.0, 1.0)):
    """A light object; `power` is the sun's strength (W/m^2) or the others' power (W)."""
    light = bpy.data.lights.new(kind.title(), kind)
    light.energy, light.color = power, color
    obj = bpy.data.objects.new(light.name, light)
    obj.location, obj.rotation_euler = location, rotation
    bpy.context.scene.collection.objects.link(obj)
    return obj


def sun_direction(rotation):
    """The direction a sun rotated by the Euler angles `rotation` shines: its -Z axis."""
    return tuple(Euler(rotation).to_matrix() @ Vector((0.0, 0.0, -1.0)))


def set_world(colour):
    """A world of uniform `colour`, whichever way this Blender reads it (viewport colour or nodes)."""
    world = bpy.data.worlds.new("World")
    world.color = colour
    if world.node_tree is not None:
        world.node_tree.nodes["Background"].inputs["Color"].default_value = (*colour, 1.0)
        world.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
    bpy.context.scene.world = world
    return world


def combined(passes, layer="ViewLayer"):
    return passes[f"{layer}.Combined"]


def head_vdb(path, n=32, cut_away=False):
    """The CT-like head in Hounsfield units, air (-1000) as the inactive background, 2 units wide."""
    grid = ct_head.grid(n, cut_away=cut_away)
    grid.write_vdb(str(path), "density")
    return str(path)


def head_scene(tmp_path, n=32, size=64):
    """The head seen from the front and above, lit by a sun from the upper left: (scene, object)."""
    scene = shaded_setup(size, size, method='PCVR')
    obj = bs.add_volume("Head", head_vdb(tmp_path / "head.vdb", n))
    camera = bs.add_camera(location=(1.5, -4.0, 2.5), ortho_scale=2.6)
    camera.rotation_euler = (-camera.location).to_track_quat('-Z', 'Y').to_euler()
    add_light('SUN', rotation=(0.6, -0.5, 0.0), power=math.pi)
    set_world((0.2, 0.2, 0.2))
    return scene, obj
