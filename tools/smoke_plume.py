# SPDX-License-Identifier: GPL-3.0-or-later

"""A synthetic smoke and fire plume and Blender's Quick Smoke and Quick Fire materials to render it with: the
volume of the bench part that sets PCVR's materials beside Cycles (tests/bench/blender_materials.py) and of the
material tests.

The plume is made here (seeded): a density that widens as it rises, smoothed noise in it, a flame near its
foot and a temperature of 3 x flame (up to 3000 K through Quick Fire's Temperature of 1000), and optionally a
`color` vector grid, written as one .vdb with Blender's bundled OpenVDB. The materials are those Blender's object.quick_smoke operator makes
(style 'SMOKE' and 'FIRE').
"""

import bpy
import numpy as np

N = 64
VOXEL = 0.1


def smooth_noise(rng, shape, width):
    """Random values low-passed by a Gaussian of `width` voxels, scaled to [0, 1]."""
    spectrum = np.fft.rfftn(rng.random(shape))
    k = np.meshgrid(*(np.fft.fftfreq(n) for n in shape[:-1]), np.fft.rfftfreq(shape[-1]), indexing="ij")
    spectrum *= np.exp(-2 * (np.pi * width) ** 2 * sum(f ** 2 for f in k))
    noise = np.fft.irfftn(spectrum, shape)
    return (noise - noise.min()) / np.ptp(noise)


def plume(n=N, seed=7):
    """{grid name: float32 values [i, j, k], k up}."""
    rng = np.random.default_rng(seed)
    i, j, k = np.indices((n, n, n), dtype=np.float64)
    radius = 0.09 * n + 0.22 * k
    r2 = ((i - n / 2) ** 2 + (j - n / 2) ** 2) / radius ** 2
    noise = smooth_noise(rng, (n, n, n), 2.5)
    density = np.exp(-2 * r2) * (0.3 + noise) * np.clip(1.2 - k / n, 0, 1)
    flame = np.exp(-4 * r2) * np.exp(-((k - 0.15 * n) / (0.12 * n)) ** 2) * (0.5 + noise)
    grids = {"density": 0.6 * density, "flame": np.clip(flame, 0, 1), "temperature": 3.0 * np.clip(flame, 0, 1)}
    for name, values in grids.items():
        values[density < 0.01] = 0.0
    return {name: values.astype(np.float32) for name, values in grids.items()}


def colour(grids):
    """A `color` grid for the plume, as a smoke simulation's: orange at its foot turning to violet as it rises,
    zero where there is no smoke. (n, n, n, 3) float32."""
    density = grids["density"]
    height = np.linspace(0.0, 1.0, density.shape[2])[None, None, :, None]
    rgb = (1 - height) * np.array([1.0, 0.45, 0.1]) + height * np.array([0.45, 0.25, 1.0])
    return np.where(density[..., None] > 0, rgb, 0.0).astype(np.float32)


def write_vdb(path, grids):
    """Write {name: values} as fog volumes of VOXEL-sized voxels into one .vdb at `path`: float grids, and vector
    grids where values are (n, n, n, 3)."""
    bpy.utils.expose_bundled_modules()
    import openvdb as vdb

    transform = vdb.createLinearTransform(voxelSize=VOXEL)
    written = []
    for name, values in grids.items():
        grid = vdb.Vec3SGrid() if values.ndim == 4 else vdb.FloatGrid()
        grid.copyFromArray(values)
        grid.name, grid.transform, grid.gridClass = name, transform, vdb.GridClass.FOG_VOLUME
        written.append(grid)
    vdb.write(path, grids=written)


def quick_material(style):
    """The material Blender's Quick Smoke operator makes for `style` ('SMOKE', 'FIRE', 'BOTH'); the objects it
    made are removed."""
    before = set(bpy.data.objects)
    bpy.ops.mesh.primitive_cube_add()
    bpy.ops.object.quick_smoke(style=style)
    domain = next(obj for obj in bpy.data.objects if obj.name.startswith("Smoke Domain"))
    material = domain.active_material
    for obj in set(bpy.data.objects) - before:
        bpy.data.objects.remove(obj)
    return material
