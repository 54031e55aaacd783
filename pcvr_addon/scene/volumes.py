# SPDX-License-Identifier: GPL-3.0-or-later

"""Scene translation: the volume instances a render sees, found before any voxel is read.

Every volume instance of the evaluated depsgraph counts (plain objects, collection instances,
geometry-node instances). A volume that comes unchanged from a file is read from that file (Blender's
`frame_filepath` already resolves sequences and frame offsets); one that modifiers or geometry nodes
made or changed is exported to a temporary file first. A fluid gas domain (a mesh) is read from its cache frame
(fluid_domain.py).

A volume's PCVR settings (volume.pcvr) and Volume > Render > Space come from the Volume datablock the user edits:
the object's own (`obj.original.data`, as the depsgraph evaluated it, its objects evaluated), also where a Mesh to
Volume or geometry-nodes modifier made the grids, whose evaluated volume is a new datablock holding the defaults.
A volume that geometry nodes make on a mesh (or any object that is not a Volume) has no such datablock: it
renders with the defaults.
"""

import dataclasses
import os
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass

import bpy
import numpy as np

from . import fluid_domain

# Splat kernels reach this many voxels beyond a voxel centre (the Gaussians' radius).
KERNEL_RADIUS_VOXELS = 2.0


@dataclass
class VolumeSource:
    """One volume instance to render."""
    name: str                     # object name, for messages
    volume: bpy.types.Volume      # evaluated volume data (None: a fluid domain)
    filepath: str                 # absolute path of the unchanged file, or "" for a procedural volume
    grid_name: str | None         # None: 'density', or else the first float grid
    object_to_world: np.ndarray   # (4, 4)
    density_scale: float
    error: str                    # why Blender could not load the file, "" when it could
    material: object = None       # bpy.types.Material: the object's active material (volume.pcvr.source 'MATERIAL')
    settings: object = None       # its PCVR settings (volume.pcvr)
    grid_names: frozenset = frozenset()  # the grids a material may name
    index_to_object: tuple | None = None  # where the file's index space lies (None: as the file's transform says)
    value_map: object = None      # fluid_domain.ValueMap: what the grid's values stand for (None: themselves)
    warnings: tuple = ()
    render_space: str = 'WORLD'   # Volume > Render > Space: 'OBJECT' or 'WORLD' (what a material's density is per)

    @property
    def has_grids(self):
        """False for a fluid domain without its cache frame (only a warning)."""
        return self.volume is not None or bool(self.filepath)

    def attribute(self, medium):
        """The grid a GridMedium of its material reads: the one it names, else the volume's own."""
        return medium.grid or self.grid_name or "density"

    def part(self, medium):
        """(VolumeSource, GridMedium) of one GridMedium of its material: the source of the grid it names."""
        return dataclasses.replace(self, grid_name=medium.grid or self.grid_name), medium


@dataclass
class DomainSource(VolumeSource):
    """A fluid gas domain's cache frame (fluid_domain.py): its density grid, and its material's others by name."""
    grids: dict = dataclasses.field(default_factory=dict)  # attribute name -> fluid_domain.DomainGrid

    def attribute(self, medium):
        # By attribute name: its grid_name is a file's grid ('density_noise' with Noise), not an attribute.
        return medium.grid or "density"

    def part(self, medium):
        grid = self.grids[self.attribute(medium)]
        warnings = ()
        if medium.colour_grid:
            warnings = (f"Fluid domain '{self.name}': the Color Attribute '{medium.colour_grid}' is not read: the "
                        "Color alone colours it",)
        source = dataclasses.replace(self, filepath=grid.filepath, grid_name=grid.grid,
                                     index_to_object=grid.index_to_object, value_map=grid.value_map, warnings=warnings)
        return source, dataclasses.replace(medium, colour_grid=None)


def placement(object_to_world, index_to_object, file_index_to_world):
    """The matrix that takes a grid's index-to-world matrix (its file's, or a coarser level's) to world space:
    the object's matrix, and for a grid placed by `index_to_object`, the file's index space mapped there first."""
    object_to_world = np.asarray(object_to_world, dtype=np.float64)
    if index_to_object is None:
        return object_to_world
    return object_to_world @ np.asarray(index_to_object) @ np.linalg.inv(np.asarray(file_index_to_world))


def _file_of(obj, volume):
    """The file the evaluated volume comes from unchanged, or "" when modifiers made or changed it."""
    if volume.packed_file or any(modifier.show_render for modifier in obj.original.modifiers):
        return ""
    filepath = volume.grids.frame_filepath
    if not filepath:
        return ""
    return os.path.normpath(bpy.path.abspath(filepath, library=volume.original.library))


def _load_error(volume):
    if len(volume.grids) or not volume.grids.error_message:
        return ""
    filepath = bpy.path.abspath(volume.filepath, library=volume.original.library)
    what = f"frame {volume.grids.frame} of the sequence '{filepath}'" if volume.is_sequence else f"'{filepath}'"
    # Blender says "not a VDB file" for a directory or a file it may not open: name the real cause.
    cause = volume.grids.error_message
    if not volume.is_sequence and os.path.isdir(filepath):
        cause = "it is a directory"
    elif not volume.is_sequence and os.path.isfile(filepath) and not os.access(filepath, os.R_OK):
        cause = "permission denied"
    return f"cannot load {what}: {cause}"


def settings_datablock(obj, depsgraph=None):
    """The Volume whose settings apply to the evaluated volume object `obj`: the user's datablock, the object's
    original data evaluated in `depsgraph` (its crop and clip objects evaluated), where that is a Volume; else the
    evaluated volume itself (a volume geometry nodes made on a mesh: the defaults)."""
    original = obj.original.data
    if not isinstance(original, bpy.types.Volume) or original == obj.data:
        return obj.data
    return original.evaluated_get(depsgraph) if depsgraph is not None else original


def source_of(obj, matrix_world, depsgraph=None):
    """The source of the evaluated volume object `obj` placed at `matrix_world` (`depsgraph`: the one that
    evaluated it, where its settings' objects are read)."""
    volume = obj.data
    datablock = settings_datablock(obj, depsgraph)
    settings = datablock.pcvr
    return VolumeSource(
        name=obj.name,
        volume=volume,
        filepath=_file_of(obj, volume),
        grid_name=settings.grid or None,
        object_to_world=np.array(matrix_world, dtype=np.float64),
        density_scale=settings.density_scale,
        error=_load_error(volume),
        material=obj.active_material,
        settings=settings,
        grid_names=frozenset(grid.name for grid in volume.grids),
        render_space=datablock.render.space,
    )


def domain_source(obj, modifier, matrix_world, frame):
    """(DomainSource or None, world corners or None) of an evaluated gas domain at a scene frame: None outside its
    cache's frames; a source without a file, only a warning, when its cache cannot be read."""
    object_to_world = np.array(matrix_world, dtype=np.float64)
    cached = fluid_domain.read_frame(obj, modifier, object_to_world, frame)
    if cached is None:
        return None, None
    warnings = (f"Fluid domain '{obj.name}': {cached.message}",) if cached.message else ()
    source = DomainSource(name=obj.name, volume=None, filepath="", grid_name=None, object_to_world=object_to_world,
                          density_scale=1.0, error="", material=obj.active_material,
                          settings=fluid_domain.default_settings(), warnings=warnings)
    density = cached.grids.get("density")
    if density is None:
        return source, None
    source = dataclasses.replace(source, filepath=density.filepath, grid_name=density.grid,
                                 index_to_object=density.index_to_object, grid_names=frozenset(cached.grids),
                                 grids=cached.grids)
    # The domain's cells are axis-aligned in object space: a kernel reaches its radius times a cell's size.
    margin = KERNEL_RADIUS_VOXELS * np.abs(np.diag(np.asarray(density.index_to_object))[:3])
    return source, grown_box_corners(cached.box[0], cached.box[1], margin, object_to_world)


def _world_corners(obj, volume, object_to_world):
    """The corners of the object's bounding box grown by the kernel radius, in world space."""
    corners = np.array([tuple(corner) for corner in obj.bound_box], dtype=np.float64)
    # A kernel ball maps to an ellipsoid in object space, whose half extent along each object axis is
    # the radius times the length of that row of the index-to-object matrix.
    row_lengths = [np.linalg.norm(np.array(grid.matrix_object)[:3, :3], axis=1) for grid in volume.grids]
    margin = KERNEL_RADIUS_VOXELS * np.max(row_lengths, axis=0)
    return grown_box_corners(corners.min(axis=0), corners.max(axis=0), margin, object_to_world)


def grown_box_corners(low, high, margin, object_to_world):
    """The corners of the object-space box `low`..`high` grown by `margin` (per object axis), in world space."""
    lo, hi = np.asarray(low) - margin, np.asarray(high) + margin
    box = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    return (object_to_world[:3, :3] @ box.T).T + object_to_world[:3, 3]


def _shown(instance, in_viewport, space):
    """Whether a volume instance shows: in renders (render visibility), or in the 3D viewport (viewport
    visibility; `space`, the SpaceView3D, adds its local view and local collections)."""
    obj = instance.object
    if not instance.show_self:
        return False
    if not in_viewport:
        # Render depsgraphs leave these out already; the viewport depsgraph of the interface does not.
        return not obj.original.hide_render
    # The viewport's depsgraph already leaves out objects hidden in the viewport.
    return space is None or instance.is_instance or obj.original.visible_in_viewport_get(space)


def in_view(depsgraph, view=None, in_viewport=False, space=None):
    """Every volume instance that shows (see _shown) and may reach `view` (a CameraView; None: anywhere)."""
    for instance in depsgraph.object_instances:
        obj = instance.object
        domain = fluid_domain.gas_domain(obj) if obj.type == 'MESH' else None
        if (obj.type != 'VOLUME' and domain is None) or not _shown(instance, in_viewport, space):
            continue
        if domain is not None:
            source, corners = domain_source(obj, domain, instance.matrix_world, depsgraph.scene.frame_current)
            if source is not None and (corners is None or view is None or view.sees_box(corners)):
                yield source
            continue
        source = source_of(obj, instance.matrix_world, depsgraph)
        if len(source.volume.grids) == 0:
            # Empty (e.g. a sequence outside its frame range), or failed to load: pass on the error.
            if source.error:
                yield source
            continue
        if view is None or view.sees_box(_world_corners(obj, source.volume, source.object_to_world)):
            yield source


@contextmanager
def exported_grids(volume):
    """The grids of the evaluated `volume` saved to a temporary .vdb file, removed afterwards."""
    fd, filepath = tempfile.mkstemp(prefix="pcvr_", suffix=".vdb")
    os.close(fd)
    try:
        if not volume.grids.save(filepath):
            raise OSError(volume.grids.error_message or "Blender could not save the evaluated grids")
        yield filepath
    finally:
        os.remove(filepath)
