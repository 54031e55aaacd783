# SPDX-License-Identifier: GPL-3.0-or-later

"""The scene's lights and world as pcvr_native's lighting, converted so that a scene looks about as bright
as in Cycles (docs/shaded-rendering-in-blender.md has the measurements behind each factor).

pcvr_native lights a sample with kd * E * max(0, n.l) * colour, E the light's colour times its strength:
a white opaque surface facing a light of strength E shows E (times kd). Cycles' white diffuse surface shows
its irradiance divided by pi (Lambert's law). So each light's strength here is the irradiance Blender's
light gives, divided by pi. A scattering medium receives the irradiance itself: pcvr_native multiplies the
strength by pi for it (its phase function, normalised over the sphere, has no 1/pi to cancel), so one
light lights Blinn-Phong and scattering volumes each as Cycles does:

| Blender light           | irradiance at distance d (Cycles, measured)  | pcvr_native strength          |
|-------------------------|----------------------------------------------|-------------------------------|
| Sun, strength S (W/m^2) | S                                            | sun, S / pi                   |
| Point, power P (W)      | P / (4 pi d^2): P spread over 4 pi sr        | point, P / (4 pi^2)           |
| Spot, power P (W)       | as a point light (the cone only cuts)        | point, P / (4 pi^2), no cone  |
| Area, power P (W)       | P / (pi d^2) on its axis (a Lambert emitter) | point, P / pi^2, all around   |

Power and strength are times 2^exposure, and colour times the blackbody colour where the light uses a
temperature. A light that is not normalised gives its power per square metre of its surface: an area
light's size, a point or spot light's sphere (4 pi r^2; 4 for radius 0, as Cycles has it). A light's
radius or size does not soften anything here: it is a point. The world (its Background node's colour times strength, or its viewport colour without nodes) is the ambient
light, and what the camera sees where the volume does not cover the image.
"""

import math
from dataclasses import dataclass

import numpy as np

from .. import compat


@dataclass(frozen=True)
class LightSpec:
    """One light in pcvr_native's terms, before pcvr_native is imported."""
    kind: str           # "sun" or "point"
    vector: tuple       # sun: the direction its light travels; point: its position (world)
    color: tuple        # linear RGB
    strength: float     # sun: irradiance / pi; point: irradiance at distance 1, / pi (scattering: times pi again)
    name: str = ""
    shadow: bool = True  # Blender's Cast Shadow: with the scene's shadows on, the volumes attenuate it
    angle: float = 0.0   # sun: Blender's Angle, the angular diameter of its disc (radians): soft shadows


def _power(light):
    """Blender's strength (sun) or power (others), times 2^exposure."""
    return light.energy * 2.0 ** getattr(light, "exposure", 0.0)


def _colour(light):
    colour = np.array(light.color, dtype=np.float64)
    if getattr(light, "use_temperature", False):
        colour *= np.array(light.temperature_color, dtype=np.float64)
    return tuple(colour)


def _area(light):
    """The emitting area of an area light in square metres."""
    size_y = light.size_y if light.shape in {'RECTANGLE', 'ELLIPSE'} else light.size
    area = light.size * size_y
    return area * math.pi / 4 if light.shape in {'DISK', 'ELLIPSE'} else area


def _unnormalised_area(light):
    """What Cycles multiplies the power of a light that is not normalised by (measured)."""
    if light.type == 'AREA':
        return _area(light)
    radius = light.shadow_soft_size
    return 4 * math.pi * radius * radius if radius > 0 else 4.0


def _casts_shadow(light):
    return bool(getattr(light, "use_shadow", True))


def light_spec(light, matrix_world, name=""):
    """The pcvr_native light for the Blender light datablock `light` placed at `matrix_world`."""
    matrix = np.array(matrix_world, dtype=np.float64)
    position = tuple(matrix[:3, 3])
    power, colour = _power(light), _colour(light)
    if light.type == 'SUN':
        # A sun shines along its object's -Z axis.
        direction = tuple(-matrix[:3, 2])
        return LightSpec("sun", direction, colour, power / math.pi, name, _casts_shadow(light), float(light.angle))
    if not getattr(light, "normalize", True):
        power *= _unnormalised_area(light)
    if light.type == 'AREA':
        return LightSpec("point", position, colour, power / math.pi ** 2, name, _casts_shadow(light))
    # POINT and SPOT
    return LightSpec("point", position, colour, power / (4 * math.pi ** 2), name, _casts_shadow(light))


def scene_lights(depsgraph):
    """Every light instance visible in the render, as LightSpecs."""
    lights = []
    for instance in depsgraph.object_instances:
        obj = instance.object
        if obj.type != 'LIGHT' or not instance.show_self or obj.original.hide_render:
            continue
        spec = light_spec(obj.data, instance.matrix_world, obj.name)
        if spec.strength > 0 and any(spec.color):
            lights.append(spec)
    return lights


def _background_node(tree):
    """The Background node that the active World Output's Surface comes from directly, or None."""
    outputs = [node for node in tree.nodes if node.bl_idname == 'ShaderNodeOutputWorld']
    active = [node for node in outputs if node.is_active_output] or outputs
    if not active:
        return None
    surface = active[0].inputs["Surface"]
    if not surface.is_linked:
        return None
    node = surface.links[0].from_node
    return node if node.bl_idname == 'ShaderNodeBackground' else None


def world_background_node(world):
    """The Background node whose colour is the world's, or None where the world's viewport colour is."""
    if world is None or not compat.world_uses_nodes(world):
        return None
    return _background_node(world.node_tree)


def world_colour(world):
    """The world's uniform colour (linear RGB): black without a world; where its nodes end in a Background
    node, that node's colour times its strength (a texture plugged in counts as the unlinked value); in any
    other case the world's viewport colour."""
    if world is None:
        return (0.0, 0.0, 0.0)
    background = world_background_node(world)
    if background is None:
        return tuple(world.color)
    colour = np.array(background.inputs["Color"].default_value[:3], dtype=np.float64)
    return tuple(colour * background.inputs["Strength"].default_value)
