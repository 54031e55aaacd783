"""Gradient opacity in Blender: a second ramp's alpha over gradient magnitudes 0..Max Gradient reaches
pcvr_native.TransferFunction's gradient and gradient_opacity; 3D Slicer's gradientOpacity; presets keep it."""

import os
import subprocess
import sys
from pathlib import Path

import bpy
import numpy as np
import pcvr_native as pn
import pytest

import blender_scenes as bs
import lit_scenes as ls
from pcvr_addon.ui import presets
from pcvr_addon.io import image_io
from pcvr_addon.scene import scene_inputs, transfer_function

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def blob_object(tmp_path, rng):
    obj = bs.add_volume("Blob", bs.write_vdb(tmp_path / "blob.vdb", bs.blob(rng)), rotation=(0.3, 0.2, 0.5))
    ls.set_ramp(obj)
    return obj


def unlit(tf):
    """The transfer function's own colours, as a volume without shading shows them (splatted regularly, as
    ls.shaded_setup's scenes are)."""
    return dict(ambient=(1, 1, 1), shading=pn.Shading(ambient=1, diffuse=0, specular=0), transfer_functions=tf,
                method="regular")


def test_the_default_curve_reaches_the_render(blob_object):
    scene = ls.shaded_setup(48, 48)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=2.5)
    settings = blob_object.data.pcvr
    settings.use_shading = False
    settings.use_gradient_opacity = True
    # No ramp of its own: factor 0 where the density is uniform, rising to 1 at 4 per world unit (the blob's
    # voxels differ by 1.2 to 3.2 per world unit, 5th to 95th percentile).
    settings.gradient_max = 4.0
    image = ls.combined(bs.render(scene))
    tf = ls.reference_transfer_function()
    modulated = pn.TransferFunction(tf.density, tf.rgba, tf.unit_distance, gradient=[0.0, 4.0], gradient_opacity=[0.0, 1.0])
    grid, camera = bs.world_grid(blob_object), bs.reference_camera()
    expected = pn.render_shaded(grid, camera, **unlit(modulated))
    plain = pn.render_shaded(grid, camera, **unlit(tf))
    # Measured: 75% of the alpha without.
    assert expected[..., 3].sum() < 0.85 * plain[..., 3].sum(), "the factor shows too little"
    # Single-precision noise, as in test_shaded.py.
    np.testing.assert_allclose(image, expected, atol=1e-5 * expected.max())


def test_the_ramp_and_range_become_control_points(blob_object):
    settings = blob_object.data.pcvr
    settings.set_gradient_opacity(20.0, [(0.0, (1, 1, 1, 0.0)), (0.25, (1, 1, 1, 1.0)), (0.25, (1, 1, 1, 0.5))])
    assert scene_inputs.ramp_inputs(settings).gradient == ()  # off until switched on
    settings.use_gradient_opacity = True
    ramp = scene_inputs.ramp_inputs(settings)
    # The step at 5 nudged apart by a millionth of the range.
    np.testing.assert_allclose(ramp.gradient, [0.0, 5.0, 5.00002], rtol=1e-6)
    np.testing.assert_allclose(ramp.gradient_opacity, [0.0, 1.0, 0.5])


def test_new_operator_copies_or_makes_the_default(blob_object):
    volume = blob_object.data
    with bpy.context.temp_override(volume=volume):
        assert bpy.ops.pcvr.gradient_opacity_new() == {'FINISHED'}
        first = volume.pcvr.gradient_opacity
        elements = transfer_function.ramp_elements(first.color_ramp)
        assert [(p, rgba[3]) for p, rgba in elements] == [(0.0, 0.0), (1.0, 1.0)]
        bpy.ops.pcvr.gradient_opacity_new()
    assert volume.pcvr.gradient_opacity not in (None, first)


def test_max_gradient_from_grid(tmp_path):
    path = ls.head_vdb(tmp_path / "head.vdb")
    low, high = pn.read_vdb(path).value_range
    obj = bs.add_volume("Head", path, scale=(2, 2, 2))
    bpy.context.view_layer.objects.active = obj
    obj.data.pcvr.density_scale = 3.0
    with bpy.context.temp_override(volume=obj.data, object=obj):
        assert bpy.ops.pcvr.gradient_max_from_grid() == {'FINISHED'}
    # The head's values (air is its inactive background), tripled, across two voxels: 32 over 2 units, doubled.
    assert low < 0 < high
    assert obj.data.pcvr.gradient_max == pytest.approx(3 * (high - low) / (2 * 2 * 2 / 32), rel=1e-6)


def test_slicer_gradient_opacity():
    gradient_max, elements = transfer_function.slicer_gradient_ramp([6, 0, 0, 10, 0.5, 40, 1])
    assert gradient_max == 40.0
    assert [(p, rgba[3]) for p, rgba in elements] == [(0.0, 0.0), (0.25, 0.5), (1.0, 1.0)]
    # Every preset Slicer ships has a factor of 1 throughout: no modulation.
    assert transfer_function.slicer_gradient_ramp([4, 0, 1, 255, 1]) is None
    with pytest.raises(ValueError, match="announces 4 numbers but holds 3"):
        transfer_function.slicer_gradient_ramp([4, 0, 0.5, 255])
    with pytest.raises(ValueError, match="increasing magnitudes"):
        transfer_function.slicer_gradient_ramp([4, 10, 0.5, 5, 1])


def test_slicer_preset_with_gradient_opacity(blob_object):
    settings = blob_object.data.pcvr
    preset = dict(scalar_opacity=[4, 0, 0, 1, 1], color_transfer=[8, 0, 1, 1, 1, 1, 1, 1, 1], shade=True,
                  ambient=0.1, diffuse=0.9, specular=0.2, specular_power=10)
    settings.apply_slicer_preset(**preset, gradient_opacity=[4, 0, 0, 30, 1])
    assert settings.use_gradient_opacity and settings.gradient_max == 30.0
    ramp = scene_inputs.ramp_inputs(settings)
    assert (ramp.gradient, ramp.gradient_opacity) == ((0.0, 30.0), (0.0, 1.0))
    settings.apply_preset("CT Bone")  # gradientOpacity 1 throughout
    assert not settings.use_gradient_opacity


def test_user_presets_keep_the_gradient_opacity(tmp_path, monkeypatch, blob_object):
    monkeypatch.setenv("BLENDER_USER_SCRIPTS", str(tmp_path / "scripts"))
    volume = blob_object.data
    volume.pcvr.set_gradient_opacity(12.5, [(0.0, (1, 1, 1, 0.25)), (0.5, (1, 1, 1, 1.0))])
    volume.pcvr.use_gradient_opacity = True
    saved = scene_inputs.ramp_inputs(volume.pcvr)
    with bpy.context.temp_override(volume=volume):
        assert bpy.ops.pcvr.transfer_function_preset_add(name="Edges") == {'FINISHED'}
    volume.pcvr.apply_preset("Cloud")
    assert not volume.pcvr.use_gradient_opacity
    volume.pcvr.apply_preset("Edges")
    assert scene_inputs.ramp_inputs(volume.pcvr) == saved


def test_the_command_line_preset_carries_it(tmp_path):
    """A Slicer preset with a gradient opacity, saved as the user's, renders through --preset with it."""
    scripts = tmp_path / "scripts"
    folder = scripts / "presets" / presets.SUBDIR
    folder.mkdir(parents=True)
    bone = (Path(presets.SHIPPED) / "CT_Bone.py").read_text()
    assert "gradient_opacity=[4, 0, 1, 255, 1]" in bone
    # Transparent where the head's density is uniform, whole from 5000 HU per world unit (its bone edges reach
    # tens of thousands: 32 voxels over 2 units).
    (folder / "Bone_Edges.py").write_text(bone.replace("gradient_opacity=[4, 0, 1, 255, 1]",
                                                       "gradient_opacity=[4, 0, 0, 5000, 1]"))
    head = ls.head_vdb(tmp_path / "head.vdb")
    images = {}
    for name in ("CT Bone", "Bone Edges"):
        output = tmp_path / f"{name}.exr"
        run = subprocess.run([sys.executable, "-m", "pcvr_addon", "render", head, "-o", output, "--mode", "shaded",
                              "--preset", name, "--magnification", "1"], cwd=ROOT, capture_output=True, text=True,
                             timeout=120, env={**os.environ, "BLENDER_USER_SCRIPTS": str(scripts)})
        assert run.returncode == 0, run.stdout + run.stderr
        images[name] = image_io.read_passes(str(output))[""][..., :3]
    difference = np.abs(images["Bone Edges"] - images["CT Bone"]).mean() / images["CT Bone"].mean()
    # Measured: 26% of the mean colour.
    assert difference > 0.1
