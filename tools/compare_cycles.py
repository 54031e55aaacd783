#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later

"""The CT head with the CT Bone preset, shaded by PCVR and by Cycles in the same scene: the pictures and the
times of docs/shaded-rendering-in-blender.md.

    .venv/bin/python tools/compare_cycles.py [--size 96] [--magnification 3] [--samples 64] [--output docs/img]

The scene is what `python -m pcvr_addon render head.vdb --mode shaded --preset "CT Bone"` renders: the head in
Hounsfield units opened towards the camera (tools/ct_head.py), framed from above by an orthographic camera, a
sun of pi W/m^2 and Blender's default grey world. Cycles renders it with a Principled Volume whose colour is
the same colour ramp over the same range and whose density is the ramp's opacity per voxel turned into an
extinction coefficient, -ln(1 - alpha) / voxel size (what pcvr_native does with it). Both images are written
with image_io (the Standard view transform: sRGB of the linear result), each render timed as a whole
(bpy.ops.render.render, reading the file included; PCVR's grid cache is emptied first). PCVR renders it twice:
with the preset's Blinn-Phong shading, and as a scattering medium with shadows (what Cycles computes, but for
light scattered more than once); the PSNR of each against Cycles is printed.
"""

import argparse
import math
import os
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import bpy  # noqa: E402

import pcvr_addon  # noqa: E402
from pcvr_addon import cache, command_scene, image_io, transfer_function  # noqa: E402
from tools import ct_head  # noqa: E402


def timed_render(scene):
    start = time.perf_counter()
    bpy.ops.render.render()
    seconds = time.perf_counter() - start
    return image_io.render_result_passes(scene)["ViewLayer.Combined"], seconds


def psnr(image, reference):
    import numpy as np
    mse = float(np.mean((np.asarray(image)[..., :3] - np.asarray(reference)[..., :3]) ** 2))
    return 10.0 * math.log10(1.0 / mse)


def cycles_material(volume_settings, voxel_size):
    """A Principled Volume that shows `volume_settings`' transfer function as Cycles understands volumes."""
    material = bpy.data.materials.new("CT Bone (Cycles)")
    if material.node_tree is None:  # before 5.0
        material.use_nodes = True
    tree = material.node_tree
    tree.nodes.clear()
    node = tree.nodes.new
    attribute = node("ShaderNodeAttribute")
    attribute.attribute_type, attribute.attribute_name = 'GEOMETRY', "density"
    to_position = node("ShaderNodeMapRange")  # Hounsfield units -> ramp position
    to_position.inputs["From Min"].default_value = volume_settings.tf_min
    to_position.inputs["From Max"].default_value = volume_settings.tf_max
    ramp = node("ShaderNodeValToRGB")
    transfer_function.set_ramp(ramp.color_ramp, transfer_function.ramp_elements(volume_settings.ramp))
    # Opacity of a voxel's thickness -> extinction per unit length: -ln(1 - alpha) / voxel size.
    clear = node("ShaderNodeMath")
    clear.operation, clear.inputs[0].default_value = 'SUBTRACT', 1.0
    log = node("ShaderNodeMath")
    log.operation, log.inputs[1].default_value = 'LOGARITHM', math.e
    extinction = node("ShaderNodeMath")
    extinction.operation, extinction.inputs[1].default_value = 'MULTIPLY', -1.0 / voxel_size
    volume = node("ShaderNodeVolumePrincipled")
    volume.inputs["Density Attribute"].default_value = ""  # the density comes from the ramp alone
    links = tree.links
    links.new(attribute.outputs["Fac"], to_position.inputs["Value"])
    links.new(to_position.outputs["Result"], ramp.inputs["Fac"])
    links.new(ramp.outputs["Color"], volume.inputs["Color"])
    links.new(ramp.outputs["Alpha"], clear.inputs[1])
    links.new(clear.outputs[0], log.inputs[0])
    links.new(log.outputs[0], extinction.inputs[0])
    links.new(extinction.outputs[0], volume.inputs["Density"])
    links.new(volume.outputs[0], node("ShaderNodeOutputMaterial").inputs["Volume"])
    return material


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", type=int, default=96, help="voxels per side of the head")
    parser.add_argument("--magnification", type=float, default=3.0, help="pixels per voxel")
    parser.add_argument("--samples", type=int, default=64, help="Cycles samples per pixel")
    parser.add_argument("--output", default=os.path.join(ROOT, "docs", "img"), help="folder of the two PNGs")
    args = parser.parse_args(argv)

    bpy.ops.wm.read_factory_settings(use_empty=True)
    pcvr_addon.register()
    try:
        directory = tempfile.mkdtemp(prefix="pcvr-compare-")
        head = os.path.join(directory, "ct_head.vdb")
        grid = ct_head.grid(args.size, cut_away=True, rotation=ct_head.opened_upwards())
        grid.write_vdb(head, "density")
        scene = bpy.context.scene
        obj = command_scene.vdb_scene(scene, head, magnification=args.magnification)
        obj.data.pcvr.apply_preset("CT Bone")
        scene.render.engine = 'PCVR'
        scene.pcvr.mode = 'SHADED'
        cache.grids.clear()
        pcvr, pcvr_seconds = timed_render(scene)
        # The same volume lit as Cycles lights a medium: single scattering of the sun through the head.
        obj.data.pcvr.shading_model, scene.pcvr.shadows = 'SCATTER', True
        cache.grids.clear()
        scattering, scattering_seconds = timed_render(scene)

        voxel_size = transfer_function.smallest_voxel_spacing(grid.index_to_world)
        obj.data.materials.append(cycles_material(obj.data.pcvr, voxel_size))
        scene.render.engine = 'CYCLES'
        scene.cycles.samples = args.samples
        cycles, cycles_seconds = timed_render(scene)

        os.makedirs(args.output, exist_ok=True)
        for name, image in (("pcvr", pcvr), ("pcvr_scattering", scattering), ("cycles", cycles)):
            image_io.write_image(os.path.join(args.output, f"ct_bone_{name}.png"), image)
        height, width = pcvr.shape[:2]
        print(f"{width} x {height} pixels, {grid.active_voxel_count:,} active voxels, "
              f"{os.cpu_count()} threads, Blender {bpy.app.version_string}")
        print(f"PCVR shaded (method {scene.pcvr.method.lower()}, post filter "
              f"{scene.pcvr.sheet_post_filter.lower()}, sheet spacing {scene.pcvr.sheet_spacing:g}): "
              f"{pcvr_seconds:.2f} s")
        print(f"PCVR scattering with shadows: {scattering_seconds:.2f} s")
        print(f"Cycles ({args.samples} samples, Principled Volume): {cycles_seconds:.2f} s "
              f"({cycles_seconds / pcvr_seconds:.0f} times as long)")
        for name, image in (("Blinn-Phong", pcvr), ("scattering with shadows", scattering)):
            print(f"PSNR of PCVR's {name} against Cycles (linear RGB, peak 1): {psnr(image, cycles):.1f} dB")
    finally:
        pcvr_addon.unregister()
    return 0


if __name__ == "__main__":
    sys.exit(main())
