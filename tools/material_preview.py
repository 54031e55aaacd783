#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later

"""A synthetic fire plume rendered with Blender's Quick Smoke and Quick Fire materials (volume.pcvr.source =
'MATERIAL'), by PCVR and optionally by Cycles: the pictures of docs/shaded-rendering-in-blender.md.

    .venv/bin/python tools/material_preview.py [--size 256] [--cycles 0] [--output docs/img]

The plume is made here (seeded): a density that widens as it rises, smoothed noise in it, a flame near its
foot and a temperature of 3 x flame (up to 3000 K through Quick Fire's Temperature of 1000), written as one
.vdb with Blender's bundled OpenVDB. The materials are those Blender's object.quick_smoke operator makes
(style 'SMOKE' and 'FIRE'). The camera looks at the plume from the side, a sun lights it from the left, the
world is dark grey; PCVR casts shadows as Cycles does (--no-shadows: none). --cycles N also renders each with Cycles at N samples (its default denoiser), timed the same
way (the whole bpy.ops.render.render).
"""

import argparse
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import bpy  # noqa: E402

import pcvr_addon  # noqa: E402
from pcvr_addon import cache, image_io  # noqa: E402

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


def write_vdb(path, grids):
    bpy.utils.expose_bundled_modules()
    import openvdb as vdb

    transform = vdb.createLinearTransform(voxelSize=VOXEL)
    written = []
    for name, values in grids.items():
        grid = vdb.FloatGrid()
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


def scene_of(vdb_path, size):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if not hasattr(bpy.types.Scene, "pcvr"):
        pcvr_addon.register()
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = 'Standard'
    volume = bpy.data.volumes.new("Plume")
    volume.filepath = vdb_path
    obj = bpy.data.objects.new("Plume", volume)
    scene.collection.objects.link(obj)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.data.type, camera.data.ortho_scale = 'ORTHO', N * VOXEL * 1.05
    camera.location, camera.rotation_euler = (N * VOXEL / 2, -10.0, N * VOXEL / 2), (np.pi / 2, 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
    sun.data.energy, sun.rotation_euler = 3.0, (0.0, 1.0, 0.3)
    scene.collection.objects.link(sun)
    world = bpy.data.worlds.new("World")
    world.color = (0.05, 0.05, 0.05)
    if world.node_tree is not None:
        world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.05, 0.05, 0.05, 1.0)
    scene.world = world
    return scene, obj


def render(scene, path):
    cache.grids.clear()
    start = time.perf_counter()
    bpy.ops.render.render()
    seconds = time.perf_counter() - start
    image_io.write_image(path, image_io.render_result_passes(scene)["ViewLayer.Combined"])
    return seconds


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--cycles", type=int, default=0, help="Cycles samples (0: PCVR only)")
    parser.add_argument("--output", default=os.path.join(ROOT, "docs", "img"))
    parser.add_argument("--no-shadows", dest="shadows", action="store_false", help="PCVR without shadows (Cycles has them)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        vdb_path = os.path.join(tmp, "plume.vdb")
        write_vdb(vdb_path, plume())
        for style in ("SMOKE", "FIRE"):
            scene, obj = scene_of(vdb_path, args.size)
            obj.data.materials.append(quick_material(style))
            obj.data.pcvr.source = 'MATERIAL'
            scene.render.engine = 'PCVR'
            scene.pcvr.mode = 'SHADED'
            scene.pcvr.shadows = args.shadows
            name = style.lower()
            print(f"{name}: PCVR {render(scene, os.path.join(args.output, f'{name}_pcvr.png')):.2f} s")
            if args.cycles:
                scene.render.engine = 'CYCLES'
                scene.cycles.samples = args.cycles
                seconds = render(scene, os.path.join(args.output, f"{name}_cycles.png"))
                print(f"{name}: Cycles {args.cycles} samples {seconds:.2f} s")


if __name__ == "__main__":
    main()
