"""The real volumes and transfer functions of the shaded benchmark against VTK (ct_head.py), so that no
tuning serves one volume alone. Each volume is fetched at run time as a user would (`apt-get download`),
cached under ~/.cache/pcvr-bench, never committed:

| key       | what                                   | source                                         | licence            | voxels          | spacing (mm)        |
|-----------|----------------------------------------|------------------------------------------------|--------------------|-----------------|---------------------|
| ct_head   | CT of a head, "ProMED CT 0051"         | Debian `invesalius-examples`,                  | GPL-2              | 256 x 256 x 108 | 0.957 x 0.957 x 1.5 |
|           | (InVesalius' sample), Hounsfield units | `examples/Cranium.inv3` (ct_head_data.py)      |                    |                 |                     |
| mr_colin  | T1 MR of a head, "Colin 27" (27 scans  | Debian `mricron-data`, `templates/ch2.nii.gz`  | BSD-3-Clause (the  | 181 x 217 x 181 | 1 x 1 x 1           |
|           | of one man averaged; MNI), 0 .. 254    | (MRIcron's template), read as `python -m       | package's          |                 |                     |
|           |                                        | pcvr_addon convert` reads it: LPS millimetres  | copyright file)    |                 |                     |
| mr_unc    | MR of a head, skull partly removed     | Debian `libvolpack1-dev`,                      | public domain      | 128 x 128 x 84  | 2 x 2 x 2 (VolPack  |
|           | (UNC Chapel Hill's "MR Brain", Siemens | `examples/brainsmall.den` (VolPack's example,  | (UNC); VolPack:    |                 | renders it with     |
|           | Magnetom, scaled down by VolPack's     | scaled from 256 x 256 x 109)                   | BSD-3-Clause       |                 | cubes; the file     |
|           | author), 0 .. 202                      |                                                |                    |                 | has no spacing)     |

No second public CT head could be had here: Debian's and PyPI's medical packages hold one CT head
(invesalius-examples), the others brains without bone (TotalSegmentator's CT atlas) or single slices
(pydicom's test files); hence two MR heads of different scanners and voxel shapes beside it.

Transfer functions (TRANSFER_FUNCTIONS, per modality): the CT head's own two of ct_head.py ("translucent",
"bone": Hounsfield units, opacity per mm) and 3D Slicer's presets as the add-on ships them ("CT Bone";
"MR Default", "MR T2 Brain"), turned into control points by the add-on's own code in Blender (bpy): the preset
applied to a volume, its ramp read back as an F12 render reads it (preset_points, in a child process). Their
opacity is per voxel (the smallest spacing), as the add-on renders them.
"""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
sys.path.append(str(HERE))

import ct_head_data  # noqa: E402

CACHE = ct_head_data.CACHE.parent


@dataclass(frozen=True)
class Volume:
    key: str
    title: str
    modality: str          # "CT" or "MR": which transfer functions apply
    package: str           # the Debian package holding it
    member: str            # its file in the package
    licence: str

    @property
    def source(self) -> str:
        return f"Debian package `{self.package}` (`apt-get download {self.package}`), `{self.member}`; {self.licence}"


VOLUMES = (
    Volume("ct_head", "CT head (InVesalius' \"ProMED CT 0051\")", "CT", ct_head_data.PACKAGE, ct_head_data.MEMBER,
           "GPL-2 (the package's copyright file)"),
    Volume("mr_colin", "MR head (\"Colin 27\", T1)", "MR", "mricron-data", "templates/ch2.nii.gz",
           "BSD-3-Clause (the package's copyright file)"),
    Volume("mr_unc", "MR head (UNC Chapel Hill's \"MR Brain\", scaled by VolPack)", "MR", "libvolpack1-dev",
           "examples/brainsmall.den", "UNC's public-domain data; VolPack BSD-3-Clause (the package's copyright file)"),
)
BY_KEY = {v.key: v for v in VOLUMES}

# Transfer functions per modality: a name of ct_head.TRANSFER_FUNCTIONS, or a preset the add-on ships.
TRANSFER_FUNCTIONS = {"CT": ("translucent", "bone", "CT Bone"), "MR": ("MR Default", "MR T2 Brain")}
PRESETS = tuple(name for names in TRANSFER_FUNCTIONS.values() for name in names if " " in name)

DEN_HEADER_BYTES = 62  # VolPack's .den: 28 int16 (version, 9 triples of extents), int16 warps, int32 length
DEN_VOXEL_MM = 2.0     # the original's 256 pixels scaled to 128 (VolPack renders the voxels as cubes)


def read_den(path: Path):
    """(values [i, j, k] float32, index_to_world) of a VolPack .den file: little-endian header, then the
    8-bit densities with x fastest. ValueError names the file and what is wrong."""
    raw = path.read_bytes()
    header = np.frombuffer(raw[:DEN_HEADER_BYTES - 4], dtype="<i2") if len(raw) >= DEN_HEADER_BYTES else None
    if header is None or header[0] != 1:
        raise ValueError(f"{path}: not a little-endian VolPack .den file (version {None if header is None else header[0]})")
    shape = tuple(int(n) for n in header[25:28])  # map_len: x, y, z
    length = int(np.frombuffer(raw[DEN_HEADER_BYTES - 4:DEN_HEADER_BYTES], dtype="<i4")[0])
    if length != int(np.prod(shape)) or len(raw) - DEN_HEADER_BYTES != length:
        raise ValueError(f"{path}: the header says {shape[0]} x {shape[1]} x {shape[2]} voxels ({length} bytes), "
                         f"the file holds {len(raw) - DEN_HEADER_BYTES}")
    values = np.frombuffer(raw[DEN_HEADER_BYTES:], dtype=np.uint8).reshape(shape[::-1]).transpose(2, 1, 0)
    return np.ascontiguousarray(values, dtype=np.float32), np.diag([DEN_VOXEL_MM] * 3 + [1.0])


def converted_vdb(source: Path, target: Path) -> Path:
    """`target`, converted from the scan `source` by the add-on's command line (as a user converts it: DICOM,
    NIfTI, ... into LPS millimetres) when it is not there yet."""
    if not target.exists():
        proc = subprocess.run([sys.executable, "-m", "pcvr_addon", "convert", str(source), "-o", str(target)],
                              cwd=REPO, capture_output=True, text=True, timeout=600)
        if proc.returncode != 0:
            raise ct_head_data.Unavailable(f"converting {source} failed: {proc.stderr.strip()[-300:]}")
    return target


def load(key: str):
    """(pn.Grid in world millimetres, its dense box's shape, that box's index_to_world) of volume `key`,
    fetched into the cache first. Raises ct_head_data.Unavailable saying why where it cannot be had."""
    import pcvr_native as pn
    volume = BY_KEY[key]
    folder = CACHE / key
    if key == "ct_head":
        values, index_to_world, _meta = ct_head_data.load()
        return pn.Grid.from_dense(values, index_to_world, background=ct_head_data.AIR_HU), values.shape, index_to_world
    local = ct_head_data.fetch_deb_member(volume.package, volume.member, folder / Path(volume.member).name)
    if local.suffix == ".den":
        values, index_to_world = read_den(local)
        return pn.Grid.from_dense(values, index_to_world, background=0.0), values.shape, index_to_world
    grid = pn.read_vdb(str(converted_vdb(local, folder / f"{key}.vdb")))
    return (grid, *dense_box(grid))


def dense_box(grid):
    """(shape, index_to_world) of the dense array Grid.to_dense returns: the grid's index box, its first
    voxel at the box's corner."""
    (i0, j0, k0), (i1, j1, k1) = grid.index_bbox
    index_to_world = np.asarray(grid.index_to_world, dtype=np.float64).copy()
    index_to_world[:3, 3] = index_to_world[:3, :3] @ [i0, j0, k0] + index_to_world[:3, 3]
    return (i1 - i0 + 1, j1 - j0 + 1, k1 - k0 + 1), index_to_world


def preset_points(names) -> dict:
    """{name: {"density", "rgba", "opacity_scale"}} of the add-on's presets `names` as Blender makes them (a child
    process with bpy runs this file): the control points' densities and colours with opacity per voxel, and the
    opacity scale the add-on divides that voxel by."""
    proc = subprocess.run([sys.executable, __file__, "--presets", *names], capture_output=True, text=True, timeout=300)
    if proc.returncode != 0:
        raise RuntimeError(f"reading the presets {', '.join(names)} in Blender failed: {proc.stderr.strip()[-400:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _presets_in_blender(names) -> dict:
    """The child's side of preset_points: each preset applied to a new Volume datablock and read back
    through scene_inputs.ramp_inputs and transfer_function.points_over_range, as F12 reads a volume."""
    import bpy
    sys.path.insert(0, str(REPO))
    import pcvr_addon
    from pcvr_addon.scene import scene_inputs, transfer_function
    bpy.ops.wm.read_factory_settings(use_empty=True)
    pcvr_addon.register()
    out = {}
    for name in names:
        volume = bpy.data.volumes.new(name)
        volume.pcvr.apply_preset(name)
        ramp = scene_inputs.ramp_inputs(volume.pcvr)
        if ramp.use_grid_range or ramp.gradient:
            raise ValueError(f"preset {name}: a range from the grid or a gradient opacity is not compared with VTK here")
        points = transfer_function.points_over_range(ramp.positions, ramp.rgba, ramp.tf_min, ramp.tf_max)
        out[name] = {"density": points.density.tolist(), "rgba": points.rgba.tolist(), "opacity_scale": ramp.opacity_scale}
    return out


if __name__ == "__main__" and sys.argv[1:2] == ["--presets"]:
    print(json.dumps(_presets_in_blender(sys.argv[2:])))
