"""An independent reference for cone-beam (C-arm) radiographs: the geometry built straight from SAD, SID, gantry,
tilt and detector offset (never from pcvr_native.cameras), and a plain numpy ray march through a grid's voxels,
trilinearly interpolated in world space. Slow and simple on purpose, so that tests and benchmarks can trust it.

Conventions (CONTRACT section 4): the source sits at isocentre + sad * d, d = Rz(gantry) (0, -1, 0) turned by
`tilt` towards +z (degrees); the detector is perpendicular to the central ray at `sid` from the source, its centre
moved by detector_offset (u, v) millimetres; image up is +z tilted with the source, image right the camera's right
seen from the source, row 0 the top; pixel (c, r) has its centre at u = (c + 0.5 - cols / 2) du + offset_u,
v = (rows / 2 - r - 0.5) dv + offset_v.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np


@dataclasses.dataclass(frozen=True)
class ConeBeamGeometry:
    """Where a C-arm's source and detector are, in world millimetres."""
    source: np.ndarray           # (3,)
    detector_centre: np.ndarray  # (3,) the detector's centre, offset included
    right: np.ndarray            # (3,) unit: image columns grow along it
    up: np.ndarray               # (3,) unit: image rows grow against it
    detector: tuple              # (cols, rows)
    pixel_spacing: tuple         # (du, dv)

    def pixel_centres(self) -> np.ndarray:
        """(rows, cols, 3) world positions of the detector's pixel centres."""
        cols, rows = self.detector
        du, dv = self.pixel_spacing
        u = (np.arange(cols) + 0.5 - cols / 2.0) * du
        v = (rows / 2.0 - np.arange(rows) - 0.5) * dv
        return (self.detector_centre + u[None, :, None] * self.right + v[:, None, None] * self.up)

    def project(self, point) -> tuple[float, float]:
        """(column, row), fractional, where the ray from the source through the world point `point` meets the
        detector; pixel (c, r) covers [c, c + 1) x [r, r + 1)."""
        point = np.asarray(point, dtype=np.float64)
        normal = np.cross(self.right, self.up)  # towards the source
        ray = point - self.source
        t = np.dot(self.detector_centre - self.source, normal) / np.dot(ray, normal)
        hit = self.source + t * ray - self.detector_centre
        cols, rows = self.detector
        du, dv = self.pixel_spacing
        return float(np.dot(hit, self.right) / du + cols / 2.0), float(rows / 2.0 - np.dot(hit, self.up) / dv)


def geometry(sad, sid, detector, pixel_spacing, isocentre=(0.0, 0.0, 0.0), gantry=0.0, tilt=0.0,
             detector_offset=(0.0, 0.0)) -> ConeBeamGeometry:
    """The C-arm's source and detector, by rotating the gantry-0 set-up: the gantry about +z, then the tilt
    about the axis that turns the source towards +z."""
    g = math.radians(gantry)
    gantry_turn = np.array([[math.cos(g), -math.sin(g), 0.0], [math.sin(g), math.cos(g), 0.0], [0.0, 0.0, 1.0]])
    to_source, up = gantry_turn @ [0.0, -1.0, 0.0], np.array([0.0, 0.0, 1.0])
    tilt_turn = _rotation(np.cross(to_source, up), math.radians(tilt))
    to_source, up = tilt_turn @ to_source, tilt_turn @ up
    source = np.asarray(isocentre, dtype=np.float64) + sad * to_source
    # Seen from the source, looking along -to_source with `up` above: right = view x up.
    right = np.cross(-to_source, up)
    centre = source - sid * to_source + detector_offset[0] * right + detector_offset[1] * up
    return ConeBeamGeometry(source, centre, right, up, tuple(detector), tuple(pixel_spacing))


def _rotation(axis, angle):
    """Rodrigues: the rotation by `angle` (radians, counter-clockwise seen from the tip) about the unit `axis`."""
    x, y, z = axis
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


def trilinear(values: np.ndarray, index_points: np.ndarray) -> np.ndarray:
    """values[i, j, k] trilinearly interpolated at fractional index points (..., 3); 0 outside the grid."""
    padded = np.pad(np.asarray(values, dtype=np.float64), 1)
    p = index_points + 1.0  # into the padded grid
    base = np.floor(p).astype(np.int64)
    frac = p - base
    inside = np.all((base >= 0) & (base < np.array(padded.shape) - 1), axis=-1)
    base = np.where(inside[..., None], base, 0)
    out = np.zeros(index_points.shape[:-1])
    for corner in range(8):
        offset = np.array([(corner >> axis) & 1 for axis in range(3)])
        weight = np.prod(np.where(offset == 1, frac, 1.0 - frac), axis=-1)
        i, j, k = (base + offset).transpose(-1, *range(base.ndim - 1))
        out += weight * padded[i, j, k]
    return np.where(inside, out, 0.0)


def march(values, index_to_world, geom: ConeBeamGeometry, samples_per_voxel: float = 2.0) -> np.ndarray:
    """(rows, cols) line integrals (density x world length) of `values` (a dense [i, j, k] array placed by the
    4x4 `index_to_world`) from the source to each pixel centre, by the midpoint rule at `samples_per_voxel`
    steps per smallest voxel spacing over the rays' stretch through the grid's box."""
    values = np.asarray(values, dtype=np.float64)
    index_to_world = np.asarray(index_to_world, dtype=np.float64)
    world_to_index = np.linalg.inv(index_to_world)
    targets = geom.pixel_centres()
    directions = targets - geom.source
    lengths = np.linalg.norm(directions, axis=-1)
    directions /= lengths[..., None]
    # The stretch of every ray inside the grid's box (one voxel of margin), from its corners' distances.
    shape = np.array(values.shape)
    corners = np.array([[x, y, z, 1.0] for x in (-1, shape[0]) for y in (-1, shape[1]) for z in (-1, shape[2])])
    corner_world = (index_to_world @ corners.T).T[:, :3]
    distances = np.linalg.norm(corner_world - geom.source, axis=1)
    near, far = max(distances.min() - 1e-9, 0.0), distances.max()
    spacing = np.linalg.norm(index_to_world[:3, :3], axis=0).min()
    step = spacing / samples_per_voxel
    t = near + (np.arange(int(math.ceil((far - near) / step))) + 0.5) * step
    out = np.zeros(targets.shape[:2])
    for row in range(targets.shape[0]):
        world = geom.source + directions[row, :, None, :] * t[None, :, None]  # (cols, steps, 3)
        index = world @ world_to_index[:3, :3].T + world_to_index[:3, 3]
        out[row] = trilinear(values, index).sum(axis=1) * step
    return out
