# SPDX-License-Identifier: GPL-3.0-or-later

"""Fluid gas domains (Quick Smoke, Quick Fire) as volume instances: the OpenVDB cache frame Mantaflow baked,
placed and shaded as Cycles shows it.

A domain is a mesh with a Fluid modifier; it has no Volume datablock, and Cycles renders it from the grids Mantaflow
read from the cache into memory. Here the cache files are read instead, as Blender writes them (its sources:
intern/mantaflow/intern/MANTA_main.cpp, strings/fluid_script.h and smoke_script.h, extern/mantaflow/.../iovdb.cpp,
blenkernel/intern/fluid.cc, makesrna/intern/rna_fluid.cc, intern/cycles/blender/volume.cpp):

- files: `<cache_directory>/data/fluid_data_NNNN.vdb` (`noise/fluid_noise_NNNN.vdb` with Noise on) and
  `config/config_NNNN.uni`, NNNN the frame with 4 digits; the cache directory relative to the .blend (or library).
  Replay caches hold the scene frame; Modular and All caches the scene frame minus the cache's frame offset.
- grids: `density`, `flame`, `temperature` (Mantaflow's *heat*), `color_r/_g/_b`, `velocity`; with Noise,
  `density_noise` and `flame_noise` at Noise's upres factor (heat never).
- placement: each file's transform is a bare scale (voxel size, no position); Cycles stretches the dense grid, one
  value per cell centre, over the evaluated domain mesh's texture space (its bounds), and so does this module. An
  adaptive domain's mesh is the box of the cells the cache frame holds: p0 + cell size x res_min .. res_max (from
  the frame's config file), kept where it was simulated if the domain moved since.
- attributes, as Cycles offers them to the material: density and flame as stored; temperature = flame ignition +
  flame x (maximum - ignition) where flame > 0.01, else 0 (Quick Fire's blackbody: 1500 K to 3000 K at its
  Temperature of 1000); heat = the heat grid x 0.5; both mapped per voxel before rendering, as Cycles maps them
  (render/prepared_scene.py). The Color attribute (a vector of the colour grids) is not read.

Its PCVR settings are the Volume settings' defaults with Source 'Material': the domain renders as its material says
in shaded mode (Quick Smoke's grey smoke, Quick Fire's flames), its density grid in X-ray and MIP.
"""

import functools
import gzip
import math
import os
import struct
import types
from dataclasses import dataclass

import bpy
import numpy as np


# config/config_NNNN.uni, gzip (MANTA::writeConfiguration): active_fields, res[3], dx, dt, p0[3], p1[3], dp0[3],
# shift[3], obj_shift_f[3], obmat[16] (column-major), base_res[3], res_min[3], res_max[3], active_color[3],
# time_total, then the cache version ("C01").
CONFIG = struct.Struct("<i3iff3f3f3f3i3f16f3i3i3i3fi")

# Cycles' temperature attribute is 0 where the flame is at most this (rna_FluidModifier_temperature_grid_get).
FLAME_THRESHOLD = 0.01


@dataclass(frozen=True)
class ValueMap:
    """An attribute Cycles computes per voxel from a cache grid's value v: offset + scale v where v > threshold,
    else 0 (a domain's temperature from its flame grid, its heat from the heat grid)."""
    threshold: float
    offset: float
    scale: float

    def points(self):
        """(values, attributes) through which the map is linear, constant beyond its ends (as
        pcvr_native.AttenuationMap takes them): values up to 10^4."""
        far = 1e4
        if math.isinf(self.threshold):
            return [-far, far], [self.offset - self.scale * far, self.offset + self.scale * far]
        above = float(np.nextafter(np.float32(self.threshold), np.float32(far)))
        return [self.threshold, above, far], [0.0, self.offset + self.scale * above, self.offset + self.scale * far]


@dataclass(frozen=True)
class CacheConfig:
    """What a cache frame's config file says of the simulation grid."""
    res: tuple        # cells of the frame's grid (the adaptive box's, or the whole domain's)
    p0: tuple         # domain mesh bounds at bake time, object space
    p1: tuple
    obmat: tuple      # 4 rows of 4: the domain's world matrix at bake time
    base_res: tuple   # cells of the whole domain
    res_min: tuple    # the frame's cells within the whole domain's
    res_max: tuple


def read_config(path):
    """CacheConfig of a config_NNNN.uni file. Raises OSError (missing, truncated, not gzip)."""
    try:
        with gzip.open(path, "rb") as file:
            raw = file.read(CONFIG.size)
    except (EOFError, gzip.BadGzipFile) as ex:
        raise OSError(f"'{path}': {ex}") from None
    if len(raw) < CONFIG.size:
        raise OSError(f"'{path}': {len(raw)} bytes, a fluid cache config holds {CONFIG.size}")
    v = CONFIG.unpack(raw)
    obmat = np.array(v[21:37], dtype=np.float64).reshape(4, 4).T
    return CacheConfig(res=v[1:4], p0=v[6:9], p1=v[9:12], obmat=tuple(map(tuple, obmat)), base_res=v[37:40],
                       res_min=v[40:43], res_max=v[43:46])


def _stamp(path):
    """What tells a cache file's versions apart: its modification time and size."""
    status = os.stat(path)
    return status.st_mtime_ns, status.st_size


@functools.lru_cache(maxsize=64)
def _cached_config(path, _stamp):
    return read_config(path)


@functools.lru_cache(maxsize=64)
def _cached_grid_names(path, _stamp):
    import pcvr_native

    return tuple(entry["name"] for entry in pcvr_native.list_grids(path))


def gas_domain(obj):
    """The Fluid modifier of an evaluated object that is a gas domain enabled for renders, or None."""
    if obj.type != 'MESH':
        return None
    for modifier in obj.modifiers:
        if (modifier.type == 'FLUID' and modifier.fluid_type == 'DOMAIN' and modifier.show_render
                and modifier.domain_settings.domain_type == 'GAS'):
            return modifier
    return None


def cache_frame(settings, frame):
    """The cache frame a scene frame shows, or None outside the cache's frames (fluid_modifier_processDomain)."""
    start, end, offset = settings.cache_frame_start, settings.cache_frame_end, settings.cache_frame_offset
    if settings.cache_type == 'REPLAY':
        return frame if start <= frame <= end else None
    low, high = (start, end + offset) if offset > 0 else (start + offset, end)
    return frame - offset if low <= frame <= high else None


def cache_directory(obj, settings):
    """The absolute cache directory of a domain (Blender makes it absolute against the .blend or its library)."""
    return os.path.normpath(bpy.path.abspath(settings.cache_directory, library=obj.original.library))


def frame_file(directory, kind, name, frame, extension=".vdb"):
    number = f"{frame:04d}" if frame >= 0 else f"{frame:05d}"
    return os.path.join(directory, kind, f"{name}_{number}{extension}")


@functools.lru_cache(maxsize=1)
def default_settings():
    """The PCVR settings of an object without a Volume datablock: the Volume settings' defaults (read from their
    properties, once), Source 'Material' with its ambient occlusion, as a Volume switched to Material has it.
    Shared: read it, never change it."""
    values = {}
    for prop in bpy.types.Volume.bl_rna.properties["pcvr"].fixed_type.properties:
        if prop.identifier == "rna_type":
            continue
        if prop.type == 'COLLECTION':
            values[prop.identifier] = ()
        elif prop.type == 'POINTER':
            values[prop.identifier] = None
        elif getattr(prop, "is_array", False):
            values[prop.identifier] = tuple(prop.default_array)
        else:
            values[prop.identifier] = prop.default
    return types.SimpleNamespace(**{**values, "source": 'MATERIAL', "ambient_occlusion": True, "ramp": None,
                                     "gradient_ramp": None})


def cells_to_object(low, high, res):
    """Index-to-object matrix of `res` cells spanning the box low..high, one value per cell centre."""
    step = (np.asarray(high, dtype=np.float64) - np.asarray(low, dtype=np.float64)) / np.asarray(res)
    matrix = np.diag([*step, 1.0])
    matrix[:3, 3] = np.asarray(low) + step / 2
    return matrix


def _texture_space(obj):
    """The evaluated mesh's texture space (its bounds, which Cycles maps the grids onto): (low, high)."""
    location, size = np.array(obj.data.texspace_location), np.array(obj.data.texspace_size)
    return location - size, location + size


def _adaptive_box(config, object_to_world):
    """An adaptive domain's box (fluid.cc create_smoke_geometry): the frame's cells, shifted back to where the
    domain was at bake time."""
    p0, p1 = np.array(config.p0), np.array(config.p1)
    cell = (p1 - p0) / np.array(config.base_res)
    shift = np.array(config.obmat)[:3, 3] - object_to_world[:3, 3]
    shift = np.linalg.inv(object_to_world[:3, :3]) @ shift
    return p0 + cell * np.array(config.res_min) + shift, p0 + cell * np.array(config.res_max) + shift


@dataclass(frozen=True)
class DomainGrid:
    """Where one attribute of a domain's material is read: a grid of a cache file, placed on the domain's cells."""
    filepath: str
    grid: str
    index_to_object: tuple                     # 4 rows of 4
    value_map: ValueMap | None = None          # what Cycles makes of the grid's values (None: them)


@dataclass(frozen=True)
class DomainFrame:
    """A domain's cache frame: its grids by attribute name (density first), or why there is none."""
    grids: dict
    box: tuple = ()                            # (low, high) in object space
    message: str = ""                          # why there is nothing to render ("" when there is)


def read_frame(obj, modifier, object_to_world, scene_frame):
    """DomainFrame of an evaluated gas domain at a scene frame. None when the scene frame is outside the cache's
    frames (Cycles renders nothing either); a DomainFrame without grids and a message when the cache cannot be
    read."""
    # The settings as the user set them (the evaluated copy's cache directory Blender may have made absolute);
    # the resolution only the evaluated domain has.
    settings = obj.original.modifiers[modifier.name].domain_settings
    frame = cache_frame(settings, scene_frame)
    if frame is None:
        return None
    directory = cache_directory(obj, settings)
    if settings.cache_data_format != 'OPENVDB':
        return DomainFrame({}, message=f"its cache in '{directory}' is in the {settings.cache_data_format} format: "
                                       "PCVR reads OpenVDB caches (Cache > Format: OpenVDB, then bake again)")
    data = frame_file(directory, "data", "fluid_data", frame)
    if not os.path.isfile(data):
        return DomainFrame({}, message=f"no cache for frame {frame} in '{os.path.dirname(data)}' (bake the "
                                       "simulation, or point Cache > Directory at its cache)")
    try:
        return _read_frame(obj, modifier, settings, object_to_world, directory, frame, data)
    except (OSError, ValueError) as ex:  # pcvr_native's VDBReadError is an OSError, its GridError a ValueError
        return DomainFrame({}, message=f"cannot read its cache frame {frame}: {ex}")


def _read_frame(obj, modifier, settings, object_to_world, directory, frame, data):
    config_path = frame_file(directory, "config", "config", frame, ".uni")
    # Cached by file version: the interface's panels find the volumes in view at every redraw.
    config = _cached_config(config_path, _stamp(config_path)) if os.path.isfile(config_path) else None
    if settings.use_adaptive_domain:
        if config is None:
            return DomainFrame({}, message=f"an adaptive domain's cache frame needs its config file: "
                                           f"'{config_path}' is missing")
        box = _adaptive_box(config, object_to_world)
    else:
        box = _texture_space(obj)
    res = tuple(config.res) if config is not None else tuple(modifier.domain_settings.domain_resolution)
    if min(res) < 1:
        return DomainFrame({}, message=f"no grid resolution for frame {frame} in '{directory}'")
    files = [(data, res, "")]
    messages = []
    if settings.use_noise:
        noise = frame_file(directory, "noise", "fluid_noise", frame)
        if os.path.isfile(noise):
            files.insert(0, (noise, tuple(settings.noise_scale * r for r in res), "_noise"))
        else:
            messages.append(f"no noise cache for frame {frame} in '{os.path.dirname(noise)}': the base resolution "
                            "rendered instead")
    present = {}
    for path, file_res, suffix in files:
        placement = tuple(map(tuple, cells_to_object(*box, file_res)))
        for name in _cached_grid_names(path, _stamp(path)):
            present.setdefault(name, DomainGrid(path, name, placement))
    grids = _attributes(present, settings, "_noise" if len(files) == 2 else "")
    if "density" not in grids:
        messages.append(f"cache frame '{data}' has no density grid")
    return DomainFrame(grids, box=tuple(map(tuple, box)), message="; ".join(messages))


def _attributes(present, settings, suffix):
    """The attributes Cycles gives a domain's material, from the grids of its cache files (by file grid name)."""
    grids = {}
    density, flame = present.get("density" + suffix), present.get("flame" + suffix)
    if density is not None:
        grids["density"] = density
    if flame is not None:
        grids["flame"] = flame
        scale = settings.flame_max_temp - settings.flame_ignition
        grids["temperature"] = DomainGrid(flame.filepath, flame.grid, flame.index_to_object, ValueMap(
            threshold=FLAME_THRESHOLD, offset=settings.flame_ignition, scale=scale))
    heat = present.get("temperature")  # Mantaflow's heat grid is called temperature in the file
    if heat is not None:
        grids["heat"] = DomainGrid(heat.filepath, heat.grid, heat.index_to_object,
                                   ValueMap(threshold=-math.inf, offset=0.0, scale=0.5))
    return grids
