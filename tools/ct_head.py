# SPDX-License-Identifier: GPL-3.0-or-later

"""A CT-like head in Hounsfield units, for the CT presets (which are in Hounsfield units) of the shaded demo,
the add-on's tests and the Cycles comparison.

pcvr_native.phantoms.ct_phantom is the 3-D Shepp-Logan head in relative attenuation (skull 1.0, brain 0.2,
ventricles 0.0, lesions 0.3). Here its values become Hounsfield units: bone 1400, brain 40 (soft tissue),
the lesions 80, and the ventricles -500, as air-filled cavities (sinuses), so that the lung preset finds
something. Outside the head is air, -1000, left inactive as the background value, the way a cropped CT
volume stores it.
"""

import numpy as np

from pcvr_native import phantoms

AIR = -1000.0
# Shepp-Logan values -> Hounsfield units, linear in between (edges are ramps a voxel wide).
ATTENUATION = (0.0, 0.2, 0.3, 1.0)
HOUNSFIELD = (-500.0, 40.0, 80.0, 1400.0)


def hounsfield_head(n=64, edge_width=2.0, cut_away=False):
    """(values [i, j, k] float32 in HU, index_to_world (4, 4)): the head spanning [-1, 1]^3, air outside
    it exactly AIR. Edges are ramps `edge_width` voxels wide: sharper ones show the voxels' terraces on
    surfaces seen at a grazing angle. With `cut_away`, the quarter x > 0, z > 0 is air too, opening the
    skull to show what is inside."""
    head = phantoms.ct_phantom(n, edge_width=edge_width)
    values = np.interp(head.values, ATTENUATION, HOUNSFIELD).astype(np.float32)
    # Outside the skull's outer ellipsoid (semi-axes 0.69, 0.92, 0.81) and its one-voxel ramp.
    i = (np.arange(n) - (n - 1) / 2) * (2.0 / n)
    x, y, z = np.meshgrid(i, i, i, indexing="ij", sparse=True)
    outside = (x / 0.69) ** 2 + (y / 0.92) ** 2 + (z / 0.81) ** 2 > 1.0
    values[outside & (head.values == 0)] = AIR
    if cut_away:
        values[(x > 0) & (z > 0) & np.ones_like(y, dtype=bool)] = AIR
    return values, head.index_to_world


def _rotation(axis, angle):
    """Right-handed rotation by `angle` radians about the coordinate axis 0 (X), 1 (Y) or 2 (Z)."""
    c, s = np.cos(angle), np.sin(angle)
    u, v = (axis + 1) % 3, (axis + 2) % 3  # the plane it turns, in right-handed order
    m = np.eye(3)
    m[u, u] = m[v, v] = c
    m[u, v], m[v, u] = -s, s
    return m


def opened_upwards():
    """The rotation that turns the cut-away quarter of the head up (+Z, towards a camera looking down, as the
    command line frames a .vdb) and then tilts the head a little, so that both the skull and what is inside
    it show: 45 degrees about Y, then 0.5 radians about X and 0.4 about Z."""
    return _rotation(2, 0.4) @ _rotation(0, 0.5) @ _rotation(1, -np.pi / 4)


def grid(n=64, edge_width=2.0, cut_away=False, rotation=None):
    """The head as a pcvr_native.Grid whose background (inactive) value is AIR, turned by the 3 x 3
    `rotation` about its centre when given."""
    import pcvr_native
    values, index_to_world = hounsfield_head(n, edge_width, cut_away)
    if rotation is not None:
        turn = np.eye(4)
        turn[:3, :3] = rotation
        index_to_world = turn @ index_to_world
    return pcvr_native.Grid.from_dense(values, index_to_world, background=AIR)
