# SPDX-License-Identifier: GPL-3.0-or-later

"""A volume's Blender material as PCVR media: what shaded mode renders when `volume.pcvr.source` is 'MATERIAL'.

The volume shader that feeds the active Material Output's Volume socket is read, directly or through Add Shader
nodes: Principled Volume, Volume Absorption, Volume Scatter and Emission. Each grid it names becomes a GridMedium,
rendered as its own native grid with its own transfer function (media_transfer_function): the density grid
absorbs and scatters, a grid linked to Emission Strength (flame) emits in proportion to its value, the
temperature grid emits as a black body. Inputs are constants, or Attribute nodes naming grids. Cycles' Principled
Volume (its SVM node) combines them so, per world unit, with D = Density x density grid and C = Color:

| Cycles                                                       | PCVR                                          |
|--------------------------------------------------------------|-----------------------------------------------|
| scattering C D, absorption max(1 - C, 0) max(1 - sqrt(A), 0) D (A: Absorption Color) | extinction: the mean over R, G, B of their sum (one extinction per sample); colour: scattering over extinction per channel |
| emission Emission Strength x Emission Color, everywhere in the volume | the same, where the density grid reaches |
| blackbody: T = Temperature x temperature grid, tint x blackbody(T) x sigma x (1 + I (T^4 - 1)), sigma = 5.67e-8 1e-6 / pi, I: Blackbody Intensity | the same; blackbody(T) from blackbody.py |
| Color Attribute (a vector grid) multiplies C                 | the same, per sample: the density-weighted colour of the voxels around it (render_shaded's albedo_grids); the extinction stays Color's |
| single scattering with the Henyey-Greenstein phase function (Anisotropy) | the same (pn.Shading(model="scatter", anisotropy=...)), the world's colour as ambient light |

A node it cannot follow (a Mix Shader, a Math node into Density, ...) leaves the media empty with a warning naming
the node: the volume then renders with its transfer function. Read on Blender's main thread (scene_inputs.read).

Cycles' units of length are the volume's Render > Space: Object (Blender's default), per unit of the object's own
space, so that scaling the object keeps its look; World, per world unit. PCVR does the same (media_transfer_function's
`length_scale`): exact for a uniform scale; with a non-uniform one, the object's units per world unit along the
camera's view (scene_inputs.object_units_per_world), where Cycles follows each ray in object space.
"""

import dataclasses
from dataclasses import dataclass

import numpy as np

from . import blackbody

# Stefan-Boltzmann's constant in Cycles' units for the Principled Volume's blackbody emission: W m^-2 K^-4, times
# 1e-6 and over pi (radiance), so that 1000 K emits about 0.018 per world unit.
BLACKBODY_SIGMA = 5.670373e-8 * 1e-6 / np.pi

# Points of a medium's transfer function over its grid's values: enough that the exponential opacity and T^4 are
# piecewise linear to well under 1% between them.
POINTS = 128


@dataclass(frozen=True)
class GridMedium:
    """What one grid adds to the medium, per world unit, as a function of its value v (clipped below at 0)."""
    grid: str | None                           # grid name; None: the volume's own grid (its Grid setting)
    extinction: float = 0.0                    # k: extinction k v
    albedo: tuple = (1.0, 1.0, 1.0)            # share of the extinction scattered, per channel: the lit colour
    anisotropy: float = 0.0                    # Henyey-Greenstein g of the scattering (the scattering model's phase)
    emission: tuple = (0.0, 0.0, 0.0)          # e: emission e v (a grid linked to Emission Strength: flame)
    constant_emission: tuple = (0.0, 0.0, 0.0)  # emitted wherever the grid reaches
    kelvin: float = 0.0                        # temperature T = kelvin v of blackbody emission; 0: none
    blackbody_intensity: float = 0.0           # I: sigma (1 + I (T^4 - 1)) times blackbody(T) times the tint
    blackbody_tint: tuple = (1.0, 1.0, 1.0)
    blackbody_colour_strength: float = 0.0     # a Blackbody node's colour of T = v (kelvin) times this strength
    colour_grid: str | None = None             # a vector grid whose colour multiplies the albedo (Color Attribute)

    def emission_at(self, values):
        """Emitted radiance (linear RGB) per world unit at each of `values` (1-D): shape (n, 3)."""
        v = np.maximum(np.asarray(values, dtype=np.float64), 0.0)[:, None]
        out = np.asarray(self.constant_emission) + v * np.asarray(self.emission)
        if self.kelvin > 0:
            t = self.kelvin * v[:, 0]
            intensity = BLACKBODY_SIGMA * (1.0 + self.blackbody_intensity * (t ** 4 - 1.0))
            # Cycles emits nothing below an intensity of 1e-5 (about 1200 K at I = 1).
            intensity = np.where(intensity > 1e-5, intensity, 0.0)
            out = out + intensity[:, None] * np.asarray(self.blackbody_tint) * blackbody.colour(t)
        if self.blackbody_colour_strength > 0:
            # The Blackbody node's colour (luminance 1) of the grid's value in kelvin, as an emission colour.
            out = out + self.blackbody_colour_strength * blackbody.colour(v[:, 0])
        return out


@dataclass(frozen=True)
class VolumeMedia:
    """A material read: one GridMedium per grid, and the warnings of what was not followed (`grids` empty: the
    volume renders with its transfer function)."""
    grids: tuple = ()
    warnings: tuple = ()


class Unsupported(Exception):
    """A node the reader cannot follow: the message names it."""


def _constant(socket):
    if hasattr(socket.default_value, "__len__"):
        return tuple(float(c) for c in socket.default_value)[:3]
    return float(socket.default_value)


def _linked_node(socket):
    """The node whose output feeds `socket` (through reroutes), or None."""
    while socket.is_linked:
        node = socket.links[0].from_node
        if node.bl_idname != 'NodeReroute':
            return node
        socket = node.inputs[0]
    return None


def _input(node, name):
    """A socket's value: ('constant', value) or ('grid', attribute name), through Attribute nodes only."""
    socket = node.inputs[name]
    source = _linked_node(socket)
    if source is None:
        return "constant", _constant(socket)
    if source.bl_idname == 'ShaderNodeAttribute' and source.attribute_type == 'GEOMETRY':
        return "grid", source.attribute_name
    raise Unsupported(f"node '{source.name}' ({source.bl_label}) feeding {node.name}'s {name}")


def _constant_input(node, name):
    kind, value = _input(node, name)
    if kind != "constant":
        raise Unsupported(f"{node.name}'s {name} takes grid '{value}'; PCVR reads it only as a constant")
    return value


def _colour_input(node, name):
    """A colour socket's value: ('constant', rgb), or ('blackbody', grid name) where a Blackbody node whose
    Temperature an Attribute node gives feeds it (a constant Temperature is a constant colour)."""
    source = _linked_node(node.inputs[name])
    if source is None or source.bl_idname != 'ShaderNodeBlackbody':
        return "constant", _constant_input(node, name)
    kind, temperature = _input(source, "Temperature")
    if kind == "grid":
        return "blackbody", temperature
    return "constant", tuple(float(c) for c in blackbody.colour(np.array([max(float(temperature), 1.0)]))[0])


def _emitting(node, colour_socket, strength_socket):
    """The media of an emission: Strength times Color, each a constant, a grid (Strength: flame) or a Blackbody
    node's colour of a temperature grid (Color), but not a grid times a grid."""
    colour_kind, colour = _colour_input(node, colour_socket)
    kind, strength = _input(node, strength_socket)
    if colour_kind == "blackbody":
        if kind == "grid":
            raise Unsupported(f"{node.name}: {strength_socket} from grid '{strength}' times a Blackbody colour of grid "
                              f"'{colour}' (PCVR renders each grid on its own)")
        return [GridMedium(grid=colour, blackbody_colour_strength=float(strength))] if strength > 0 else []
    if kind == "grid":
        return [GridMedium(grid=strength, emission=tuple(colour))]
    return [GridMedium(grid=None, constant_emission=tuple(float(c) for c in strength * np.asarray(colour)))] if strength > 0 else []


def _rgb(colour):
    return np.asarray(colour, dtype=np.float64)


def _scattering_medium(grid, scattering, absorption, anisotropy):
    """A GridMedium of per-channel scattering and absorption coefficients per unit value: one extinction (their
    sum's mean over R, G, B) and the scattered share per channel as the colour."""
    extinction = scattering + absorption
    k = float(np.mean(extinction))
    albedo = tuple(float(s / e) if e > 0 else 0.0 for s, e in zip(scattering, extinction))
    return GridMedium(grid=grid, extinction=k, albedo=albedo, anisotropy=anisotropy)


def _density_grid(node, density_socket="Density", attribute_socket="Density Attribute"):
    """(grid name or None, constant factor) of a density: an Attribute link, else the Density Attribute."""
    kind, value = _input(node, density_socket)
    if kind == "grid":
        return value, 1.0
    attribute = node.inputs[attribute_socket].default_value if attribute_socket in node.inputs else ""
    return (attribute or None), value


def _principled(node):
    grid, density = _density_grid(node)
    colour = _rgb(_constant_input(node, "Color"))
    absorption_colour = _rgb(_constant_input(node, "Absorption Color"))
    scattering = colour * density
    absorption = np.maximum(1.0 - colour, 0.0) * np.maximum(1.0 - np.sqrt(np.maximum(absorption_colour, 0.0)), 0.0) * density
    # The density grid absorbs and scatters, and carries a constant emission (one native grid, not two).
    medium = _scattering_medium(grid, scattering, absorption, float(_constant_input(node, "Anisotropy")))
    medium = dataclasses.replace(medium, colour_grid=node.inputs["Color Attribute"].default_value or None)
    emitted = _emitting(node, "Emission Color", "Emission Strength")
    # A constant emission rides on the density grid (one native grid, not two).
    constant = [m for m in emitted if m.grid is None]
    if constant:
        medium = dataclasses.replace(medium, constant_emission=constant[0].constant_emission)
    media = [medium] if density > 0 or constant else []
    media += [m for m in emitted if m.grid is not None]
    intensity = float(_constant_input(node, "Blackbody Intensity"))
    if intensity > 1e-3:
        attribute = node.inputs["Temperature Attribute"].default_value
        kind, kelvin = _input(node, "Temperature")
        if kind == "grid" or not attribute:
            raise Unsupported(f"{node.name}: blackbody emission needs a constant Temperature and a Temperature "
                              "Attribute naming a grid")
        media.append(GridMedium(grid=attribute, kelvin=float(kelvin), blackbody_intensity=intensity,
                                blackbody_tint=tuple(_constant_input(node, "Blackbody Tint"))))
    return media


def _absorption(node):
    grid, density = _density_grid(node, attribute_socket="")
    colour = _rgb(_constant_input(node, "Color"))
    return [_scattering_medium(grid, np.zeros(3), np.maximum(1.0 - colour, 0.0) * density, 0.0)] if density > 0 else []


def _scatter(node):
    grid, density = _density_grid(node, attribute_socket="")
    colour = _rgb(_constant_input(node, "Color"))
    anisotropy = float(_constant_input(node, "Anisotropy")) if "Anisotropy" in node.inputs else 0.0
    return [_scattering_medium(grid, colour * density, np.zeros(3), anisotropy)] if density > 0 else []


def _emission(node):
    return _emitting(node, "Color", "Strength")


def _add(node):
    return _shader(node.inputs[0]) + _shader(node.inputs[1])


SHADERS = {
    'ShaderNodeVolumePrincipled': _principled,
    'ShaderNodeVolumeAbsorption': _absorption,
    'ShaderNodeVolumeScatter': _scatter,
    'ShaderNodeEmission': _emission,
    'ShaderNodeAddShader': _add,
}


def _shader(socket):
    node = _linked_node(socket)
    if node is None:
        return []
    reader = SHADERS.get(node.bl_idname)
    if reader is None:
        raise Unsupported(f"node '{node.name}' ({node.bl_label}) feeding the volume shader")
    return reader(node)


def read(material):
    """VolumeMedia of a Material (or None). Never raises: what cannot be followed is a warning."""
    if material is None or material.node_tree is None:
        return VolumeMedia(warnings=("no material with nodes: rendered with the transfer function",))
    output = material.node_tree.get_output_node('CYCLES')
    if output is None or not output.inputs["Volume"].is_linked:
        return VolumeMedia(warnings=(f"material '{material.name}' has no volume shader: rendered with the transfer "
                                     "function",))
    try:
        media = _shader(output.inputs["Volume"])
    except Unsupported as ex:
        return VolumeMedia(warnings=(f"material '{material.name}': cannot follow {ex}: rendered with the transfer "
                                     "function",))
    if not media:
        return VolumeMedia(warnings=(f"material '{material.name}': its volume shader adds neither density nor light: "
                                     "rendered with the transfer function",))
    return VolumeMedia(grids=tuple(media))


def media_transfer_function(medium, value_range, density_scale, unit_distance, length_scale=1.0):
    """(density, rgba, emission) control points of a GridMedium over its grid's values (times the density
    scale), for pcvr_native.TransferFunction with `unit_distance` (world units). `length_scale`: the medium's
    units of length per world unit (Volume > Render > Space: Object, the object's units along the view; World,
    1): its extinction and emission, per unit of its length, times that per world unit."""
    low, high = (float(v) * density_scale for v in value_range)
    top = max(high, 1e-6)
    values = np.linspace(min(low, 0.0), top, POINTS)
    opacity = -np.expm1(-medium.extinction * length_scale * np.maximum(values, 0.0) * unit_distance)
    rgba = np.column_stack([np.tile(medium.albedo, (POINTS, 1)), np.minimum(opacity, 1.0)])
    return values, rgba, length_scale * medium.emission_at(values)
