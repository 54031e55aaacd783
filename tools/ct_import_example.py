#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later

"""The README's scan import: a public CT series brought in through File > Import > PCVR Volume (its operator,
pcvr.import_volume: converted to a .vdb in Hounsfield units, placed in metres, the CT Bone preset applied) and
rendered shaded by PCVR from the front, as a user would in Blender.

The data: dcm_qa_ct, Chris Rorden's DICOM-to-NIfTI validation set (BSD 2-Clause licence; repository
neurolabusc/dcm_qa_ct on GitHub). Its Philips Ingenuity phantom scan, series 202: 140 slices of 512 x 512,
0.45 x 0.45 x 1 mm. Get it as a user would, then run:

    git clone --depth 1 https://github.com/neurolabusc/dcm_qa_ct /tmp/dcm_qa_ct
    .venv/bin/python tools/ct_import_example.py /tmp/dcm_qa_ct/In/Philips/S21570/S2020 -o docs/img/ct_import_dicom.png

The folder holds one series; a folder with several lists them, and --series picks one.
"""

import argparse
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import bpy  # noqa: E402
from mathutils import Vector  # noqa: E402

import pcvr_addon  # noqa: E402
from pcvr_addon.cli import command_scene  # noqa: E402
from pcvr_addon.io import image_io  # noqa: E402

# From the front (Blender's -Y: the patient's face), a little from the patient's right and from above.
VIEW_DIRECTION = Vector((0.4, 1.0, -0.2)).normalized()
# A sun from the front, above and to the patient's left: the face lit, the head rest behind in shade.
LIGHT_DIRECTION = (-0.4, 0.7, -0.6)


def render(series_folder, output, series=None, resolution=(640, 480), preset="CT Bone"):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    pcvr_addon.register()
    try:
        with tempfile.TemporaryDirectory() as vdb_folder:
            first_file = sorted(os.path.join(series_folder, name) for name in os.listdir(series_folder))[0]
            result = bpy.ops.pcvr.import_volume(filepath=first_file, unit_scale=0.001, series=series or "",
                                                directory_for_vdb=vdb_folder)
            if result != {'FINISHED'}:
                raise RuntimeError(f"import failed: {result}")
            obj = bpy.context.view_layer.objects.active
            if preset != "CT Bone":
                obj.data.pcvr.apply_preset(preset)
            scene = bpy.context.scene
            scene.render.engine = 'PCVR'
            scene.pcvr.mode = 'SHADED'
            scene.render.resolution_x, scene.render.resolution_y = resolution
            scene.render.resolution_percentage = 100
            _camera(scene, obj)
            command_scene._light(scene, LIGHT_DIRECTION)
            bpy.ops.render.render()
            image_io.write_image(output, image_io.render_result_passes(scene)["ViewLayer.Combined"])
            print(f"wrote {output}: {obj.data['pcvr_description']}")
    finally:
        pcvr_addon.unregister()


def _camera(scene, obj):
    """An orthographic camera looking along VIEW_DIRECTION at the volume's bounding box, fitting it."""
    corners = [obj.matrix_world @ Vector(corner) for corner in obj.bound_box]
    centre = sum(corners, Vector()) / 8
    size = max((a - b).length for a in corners for b in corners)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.data.type = 'ORTHO'
    camera.data.ortho_scale = 0.8 * size
    camera.data.clip_end = 4 * size
    camera.location = centre - VIEW_DIRECTION * 2 * size
    camera.rotation_euler = VIEW_DIRECTION.to_track_quat('-Z', 'Y').to_euler()
    scene.collection.objects.link(camera)
    scene.camera = camera


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("series_folder")
    parser.add_argument("-o", "--output", default=os.path.join(ROOT, "docs", "img", "ct_import_dicom.png"))
    parser.add_argument("--series", help="the series to import when the folder holds several")
    parser.add_argument("--preset", default="CT Bone")
    args = parser.parse_args()
    render(args.series_folder, args.output, args.series, preset=args.preset)
