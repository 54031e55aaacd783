# SPDX-License-Identifier: GPL-3.0-or-later

"""Transfer functions: a Blender colour ramp spread over a density range, as pcvr_native's control points.

A volume's ramp is the `color_ramp` of a Texture datablock that `volume.pcvr.transfer_function` points to: a
Texture is an ID, so the ramp is saved with the .blend, undone with the rest of the file, linked along with
the volume from a library, and shared between volumes (or made single-user) like any datablock, while
`template_color_ramp` edits it with Blender's own widget. A volume without one renders with DEFAULT_RAMP.

The ramp's colour is linear RGB (Blender's scene-linear, as a colour picker shows it) and its alpha the
opacity of one voxel's thickness (pcvr_native's unit_distance: the smallest voxel spacing, divided by the
volume's opacity scale). Ramp position 0 is the density `tf_min`, position 1 `tf_max`; beyond them the end
colours hold. Linear RGB ramps become control points exactly; other interpolations and colour modes are
sampled through ColorRamp.evaluate.
"""

from dataclasses import dataclass

import numpy as np

# Black and transparent at the lowest density to white at the highest, where a voxel's thickness stops 5% of
# the light: grey levels that follow the density, and a volume a few dozen voxels deep that is neither
# invisible nor a white block, whatever the grid's units (the range follows the grid's values by default).
DEFAULT_RAMP = (
    (0.0, (0.0, 0.0, 0.0, 0.0)),
    (1.0, (1.0, 1.0, 1.0, 0.05)),
)

# Gradient opacity (shaded mode): a second ramp whose alpha is the factor on the opacity over gradient
# magnitudes 0..gradient_max (density units per world unit; the ends hold beyond). By default uniform regions
# vanish and boundaries keep their opacity. Its colour is unused.
DEFAULT_GRADIENT_RAMP = (
    (0.0, (1.0, 1.0, 1.0, 0.0)),
    (1.0, (1.0, 1.0, 1.0, 1.0)),
)

# Blender's colour ramps hold at most this many elements.
MAX_ELEMENTS = 32

# Positions of the samples of a ramp that is not piecewise linear in RGB.
SAMPLES = 256


@dataclass
class ControlPoints:
    """A transfer function in the form pcvr_native.TransferFunction takes."""
    density: np.ndarray  # (n,), strictly increasing
    rgba: np.ndarray     # (n, 4): linear RGB and opacity per unit distance

    def colour_at(self, density):
        """RGBA at each of `density` (any shape): linear between the points, the end values beyond them,
        as pcvr_native classifies."""
        density = np.asarray(density, dtype=np.float64)
        channels = [np.interp(density, self.density, self.rgba[:, c]) for c in range(4)]
        return np.stack(channels, axis=-1)


def ramp_elements(ramp, default=DEFAULT_RAMP):
    """The (position, rgba) pairs of a ColorRamp, or `default`'s when `ramp` is None."""
    if ramp is None:
        return [(position, tuple(rgba)) for position, rgba in default]
    return [(element.position, tuple(element.color)) for element in ramp.elements]


def _strictly_increasing(positions, span):
    """Positions nudged apart where elements coincide (a step), by a hair of the range."""
    positions = np.array(positions, dtype=np.float64)
    nudge = 1e-6 * span
    for i in range(1, len(positions)):
        if positions[i] <= positions[i - 1]:
            positions[i] = positions[i - 1] + nudge
    return positions


def _sampled(ramp):
    """(positions, rgba) of a ramp evaluated where it is not linear: evenly, and just either side of each
    element so that steps stay sharp."""
    edges = [element.position for element in ramp.elements]
    positions = np.unique(np.clip(np.concatenate([
        np.linspace(0.0, 1.0, SAMPLES + 1), np.subtract(edges, 1e-6), np.add(edges, 1e-6)]), 0.0, 1.0))
    return positions, np.array([ramp.evaluate(float(p)) for p in positions], dtype=np.float64)


def ramp_points(ramp, default=DEFAULT_RAMP):
    """(positions in 0..1, rgba) of `ramp` (a ColorRamp, or None for `default`) as control points: its
    elements where it is linear in RGB, else samples. Reads Blender data: call on Blender's main thread."""
    if ramp is None or (ramp.interpolation == 'LINEAR' and ramp.color_mode == 'RGB'):
        elements = ramp_elements(ramp, default)
        positions = [position for position, _rgba in elements]
        rgba = np.array([colour for _position, colour in elements], dtype=np.float64)
        return np.asarray(positions, dtype=np.float64), rgba
    return _sampled(ramp)


def points_over_range(positions, rgba, tf_min, tf_max):
    """ControlPoints of ramp points (see ramp_points) spread over densities tf_min..tf_max. Raises ValueError
    when the range is empty."""
    if not tf_max > tf_min:
        raise ValueError(f"the transfer function's range {tf_min:g} to {tf_max:g} is empty")
    span = tf_max - tf_min
    density = _strictly_increasing(tf_min + np.asarray(positions, dtype=np.float64) * span, span)
    rgba = np.asarray(rgba, dtype=np.float64)
    return ControlPoints(density=density, rgba=np.clip(rgba, 0.0, [np.inf, np.inf, np.inf, 1.0]))


def control_points(ramp, tf_min, tf_max):
    """The control points of `ramp` (a ColorRamp, or None for DEFAULT_RAMP) over densities tf_min..tf_max.
    Raises ValueError when the range is empty."""
    return points_over_range(*ramp_points(ramp), tf_min, tf_max)


def gradient_points(positions, rgba, gradient_max):
    """(gradient magnitudes, factors) of a gradient-opacity ramp's points (see ramp_points): positions 0..1
    spread over magnitudes 0..gradient_max, the factor the alpha. Raises ValueError unless gradient_max > 0."""
    if not gradient_max > 0:
        raise ValueError(f"the gradient opacity's Max Gradient must be positive, not {gradient_max:g}")
    gradient = _strictly_increasing(np.asarray(positions, dtype=np.float64) * gradient_max, gradient_max)
    return gradient, np.clip(np.asarray(rgba, dtype=np.float64)[:, 3], 0.0, 1.0)


def set_ramp(ramp, elements, interpolation='LINEAR', color_mode='RGB'):
    """Make `ramp` hold exactly `elements`, (position, rgba) pairs."""
    if not 1 <= len(elements) <= MAX_ELEMENTS:
        raise ValueError(f"a colour ramp holds 1 to {MAX_ELEMENTS} elements, not {len(elements)}")
    ramp.color_mode = color_mode
    ramp.interpolation = interpolation
    while len(ramp.elements) > 1:
        ramp.elements.remove(ramp.elements[-1])
    (first_position, first_rgba), rest = elements[0], elements[1:]
    ramp.elements[0].position, ramp.elements[0].color = first_position, first_rgba
    for position, rgba in rest:
        ramp.elements.new(position).color = rgba


def new_ramp_texture(textures, name, elements=DEFAULT_RAMP):
    """A new Texture datablock in `textures` (bpy.data.textures) whose colour ramp holds `elements`."""
    texture = textures.new(name, 'BLEND')
    texture.use_color_ramp = True
    set_ramp(texture.color_ramp, elements)
    return texture


def grid_range(value_range, density_scale):
    """The density range a grid's values span (times its density scale), widened down to 0, the density of
    empty space: a grid of one value still spans a range, and a fog volume fades in from nothing."""
    low, high = sorted(density_scale * value for value in value_range)
    low = min(low, 0.0)
    return (low, high) if high > low else (low, low + 1.0)


def density_range(settings, value_range, density_scale):
    """(lowest, highest) density of a volume's ramp: its tf_min and tf_max, or the grid's range."""
    if settings.use_grid_range:
        return grid_range(value_range, density_scale)
    return settings.tf_min, settings.tf_max


def smallest_voxel_spacing(index_to_world):
    """The shortest edge of a voxel in world units: pcvr_native's default unit distance."""
    return float(np.linalg.norm(np.asarray(index_to_world)[:3, :3], axis=0).min())


def edge_gradient(value_range, density_scale, index_to_world):
    """|gradient| per world unit of a sharp edge across a grid's whole range (grid_range): the range over two of
    its shortest voxel spacings, as the kernels spread a one-voxel step. A start for the gradient opacity's
    Max Gradient."""
    low, high = grid_range(value_range, density_scale)
    return (high - low) / (2.0 * smallest_voxel_spacing(index_to_world))


# -------------------------------------------------------------------------------------------------
# 3D Slicer's volume-rendering presets (Modules/Loadable/VolumeRendering/Resources/presets.xml) give VTK's
# transfer functions: a scalar opacity [count, x0, a0, x1, a1, ...] and a colour transfer function
# [count, x0, r0, g0, b0, ...], each piecewise linear over the scalar x, and a gradient opacity
# [count, g0, f0, g1, f1, ...] over the gradient magnitude g. VTK blends their colours as they
# are shown on screen, without colour management, so they are display (sRGB) values, decoded here to the
# linear values of Blender's ramps: under the Standard view transform a preset shows Slicer's colours.

def _vtk_points(flat, width):
    """[count, v, v, ...] -> (count / width, width) rows."""
    count = int(flat[0])
    values = np.asarray(flat[1:], dtype=np.float64)
    if len(values) != count or count % width:
        raise ValueError(f"a VTK function of {width}-tuples announces {count} numbers but holds {len(values)}")
    return values.reshape(-1, width)


def srgb_decode(values):
    values = np.asarray(values, dtype=np.float64)
    return np.where(values <= 0.04045, values / 12.92, ((values + 0.055) / 1.055) ** 2.4)


def slicer_ramp(scalar_opacity, color_transfer):
    """(tf_min, tf_max, elements) of a ramp that holds a Slicer preset: one element at every scalar where
    either function has a point, so that both stay piecewise linear as VTK has them."""
    opacity = _vtk_points(scalar_opacity, 2)
    colour = _vtk_points(color_transfer, 4)
    scalars = np.unique(np.concatenate([opacity[:, 0], colour[:, 0]]))
    if len(scalars) > MAX_ELEMENTS:
        raise ValueError(f"the preset has {len(scalars)} distinct points; a colour ramp holds {MAX_ELEMENTS}")
    rgb = srgb_decode(np.stack([np.interp(scalars, colour[:, 0], colour[:, c]) for c in (1, 2, 3)], axis=-1))
    alpha = np.interp(scalars, opacity[:, 0], opacity[:, 1])
    tf_min, tf_max = float(scalars[0]), float(scalars[-1])
    positions = (scalars - tf_min) / (tf_max - tf_min)
    elements = [(float(p), (*map(float, c), float(a))) for p, c, a in zip(positions, rgb, alpha)]
    return tf_min, tf_max, elements


def slicer_gradient_ramp(gradient_opacity):
    """(gradient_max, elements) of a gradient-opacity ramp that holds a Slicer preset's gradientOpacity, or None
    where its factor is 1 at every point (every preset Slicer ships): no modulation, the cheaper render."""
    points = _vtk_points(gradient_opacity, 2)
    gradient, factor = points[:, 0], points[:, 1]
    if np.all(factor == 1.0):
        return None
    if len(points) > MAX_ELEMENTS:
        raise ValueError(f"the preset's gradient opacity has {len(points)} points; a colour ramp holds {MAX_ELEMENTS}")
    if gradient[0] < 0 or np.any(np.diff(gradient) <= 0) or np.any((factor < 0) | (factor > 1)):
        raise ValueError("a gradient opacity needs increasing magnitudes from 0 up and factors in [0, 1]")
    gradient_max = float(gradient[-1]) if gradient[-1] > 0 else 1.0
    elements = [(float(g / gradient_max), (1.0, 1.0, 1.0, float(f))) for g, f in points]
    return gradient_max, elements
