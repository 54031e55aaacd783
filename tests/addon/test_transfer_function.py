"""Transfer functions: the colour ramp as control points, its default, the range from the grid; presets shipped
and saved by the user; the ramp through save and reload, linking and undo."""

import os

import bpy
import numpy as np
import pcvr_native as pn
import pytest

import blender_scenes as bs
import lit_scenes as ls
from pcvr_addon.ui import presets
from pcvr_addon.scene import transfer_function

SHIPPED = sorted(presets.display_name(name) for name in os.listdir(presets.SHIPPED) if name.endswith(".py"))
REQUIRED = {"CT Bone", "CT Soft Tissue", "CT Muscle", "CT Lung", "MR Default", "Cloud"}


@pytest.fixture
def volume(tmp_path):
    return bs.add_volume("Box", bs.write_vdb(tmp_path / "box.vdb", bs.box())).data


def ramp_state(settings):
    """What a transfer function is: its elements, range and material."""
    return (transfer_function.ramp_elements(settings.ramp), settings.ramp.interpolation, settings.use_grid_range,
            settings.tf_min, settings.tf_max, settings.opacity_scale, settings.use_shading, settings.ambient,
            settings.diffuse, settings.specular, settings.shininess)


def flat(elements):
    """(position, rgba) pairs as rows of five numbers."""
    return np.array([(position, *rgba) for position, rgba in elements])


def test_linear_ramp_gives_its_elements_as_control_points(volume):
    settings = volume.pcvr
    settings.set_transfer_function(-100.0, 300.0, [(0.0, (0, 0, 0, 0)), (0.25, (1, 0, 0, 0.5)), (0.25, (0, 1, 0, 0.5)),
                                                    (1.0, (1, 1, 1, 1))])
    points = transfer_function.control_points(settings.ramp, settings.tf_min, settings.tf_max)
    # Two elements in one place (a step) are nudged a millionth of the range apart.
    np.testing.assert_allclose(points.density, [-100.0, 0.0, 0.0004, 300.0], atol=1e-9)
    assert (np.diff(points.density) > 0).all()
    np.testing.assert_allclose(points.rgba[1:3, :3], [[1, 0, 0], [0, 1, 0]])


def test_other_interpolations_are_sampled(volume):
    settings = volume.pcvr
    settings.set_transfer_function(0.0, 1.0, [(0.0, (0, 0, 0, 0)), (0.5, (1, 1, 1, 1))], interpolation='CONSTANT')
    points = transfer_function.control_points(settings.ramp, 0.0, 1.0)
    # A step at 0.5: black and clear below, white and opaque above.
    np.testing.assert_array_equal(points.colour_at([0.3, 0.499, 0.501, 0.9])[:, 3], [0, 0, 1, 1])
    with pytest.raises(ValueError, match="range 1 to 1 is empty"):
        transfer_function.control_points(settings.ramp, 1.0, 1.0)


def test_default_is_a_grey_ramp_over_the_grid_values(tmp_path):
    """Without a ramp of its own a volume renders grey and translucent, wherever its values lie: a CT in
    Hounsfield units shows neither nothing nor a white block."""
    scene, obj = ls.head_scene(tmp_path)
    assert obj.data.pcvr.transfer_function is None and obj.data.pcvr.use_grid_range
    image = ls.combined(bs.render(scene))
    alpha, colour = image[..., 3], image[..., :3]
    covered = alpha > 0.05
    # Measured: the whole head, 42% of the image, covered; alpha up to 0.58 (32 voxels deep); the brightest
    # channel 0.16; grey.
    assert 0.3 < covered.mean() < 0.6
    assert 0.3 < alpha.max() < 0.95 and 0.05 < colour.max() < 0.5
    np.testing.assert_allclose(colour[..., 0], colour[..., 2], atol=1e-6)


def test_range_from_grid_operator(tmp_path):
    path = ls.head_vdb(tmp_path / "head.vdb")
    low, high = pn.read_vdb(path).value_range
    obj = bs.add_volume("Head", path)
    bpy.context.view_layer.objects.active = obj
    obj.data.pcvr.density_scale = 2.0
    with bpy.context.temp_override(volume=obj.data, object=obj):
        assert bpy.ops.pcvr.transfer_function_range_from_grid() == {'FINISHED'}
    settings = obj.data.pcvr
    # The head's values (air is its inactive background), doubled.
    assert low < 0 < high and (settings.tf_min, settings.tf_max) == pytest.approx((2 * low, 2 * high))
    assert not settings.use_grid_range


def test_new_operator_copies_or_makes_the_default(volume):
    with bpy.context.temp_override(volume=volume):
        bpy.ops.pcvr.transfer_function_new()
        first = volume.pcvr.transfer_function
        np.testing.assert_allclose(flat(transfer_function.ramp_elements(first.color_ramp)),
                                   flat(transfer_function.DEFAULT_RAMP), rtol=1e-7)
        first.color_ramp.elements[0].color = (1, 0, 0, 0)
        bpy.ops.pcvr.transfer_function_new()
    second = volume.pcvr.transfer_function
    assert second != first and second.color_ramp.elements[0].color[0] == 1.0


def test_required_presets_are_shipped():
    assert REQUIRED <= set(SHIPPED)


def test_slicer_preset_numbers(volume):
    volume.pcvr.apply_preset("CT-Bone")  # Slicer's spelling works too
    settings = volume.pcvr
    assert (settings.tf_min, settings.tf_max, settings.use_grid_range) == (-3024.0, 3071.0, False)
    elements = transfer_function.ramp_elements(settings.ramp)
    positions = [(hu + 3024) / 6095 for hu in (-3024, -16.4458, 641.385, 3071)]
    np.testing.assert_allclose([position for position, _rgba in elements], positions, atol=1e-7)
    # Slicer's display colours decoded to linear: (0.905882, 0.815686, 0.552941) at 641 HU.
    np.testing.assert_allclose(elements[2][1], [0.799102, 0.630757, 0.266356, 0.715686], atol=1e-6)
    assert (settings.ambient, settings.diffuse, settings.specular, settings.shininess) == pytest.approx((0.1, 0.9, 0.2, 10))


def test_unknown_preset_names_the_ones_there_are(volume):
    with pytest.raises(KeyError, match="no transfer-function preset 'CT Teeth'; there are: .*CT Bone"):
        volume.pcvr.apply_preset("CT Teeth")


@pytest.mark.parametrize("name", SHIPPED)
def test_each_preset_renders_the_ct_head(tmp_path, name):
    scene, obj = ls.head_scene(tmp_path)
    obj.data.pcvr.apply_preset(name)
    image = ls.combined(bs.render(scene))
    alpha = image[..., 3]
    covered = alpha > 0.05
    colour = image[covered, :3]
    # Measured over the presets: from 2.4% of the image covered (CT Lung: the cavities) to 42% (the whole
    # head); the brightest channel from 0.38 (CT Bone) to 1.03 (CT AAA); where lit, channels spread over
    # 0.37 at least from shadow to light (the unlit presets, CT Soft Tissue and MR MIP, are flat).
    assert 0.015 < covered.mean() < 0.5, f"{name}: {covered.mean():.1%} covered"
    assert 0.3 < colour.max() < 1.5, f"{name}: brightest channel {colour.max():.2f}"
    if obj.data.pcvr.use_shading:
        assert np.ptp(colour, axis=0).max() > 0.3, f"{name}: spread {np.ptp(colour, axis=0).max():.2f}"
    assert np.isfinite(image).all()


def test_user_presets_save_and_load(tmp_path, monkeypatch, volume):
    monkeypatch.setenv("BLENDER_USER_SCRIPTS", str(tmp_path / "scripts"))
    settings = volume.pcvr
    settings.set_transfer_function(-5.0, 5.0, [(0.0, (0.1, 0.2, 0.3, 0.0)), (0.7, (1.0, 0.5, 0.25, 0.6))],
                                   interpolation='EASE')
    settings.opacity_scale, settings.use_shading, settings.shininess = 2.5, False, 30.0
    saved = ramp_state(settings)
    with bpy.context.temp_override(volume=volume):
        assert bpy.ops.pcvr.transfer_function_preset_add(name="My Bone") == {'FINISHED'}
    assert (tmp_path / "scripts" / "presets" / presets.SUBDIR / "My_Bone.py").is_file()

    volume.pcvr.apply_preset("CT Lung")
    assert ramp_state(volume.pcvr) != saved
    volume.pcvr.apply_preset("My Bone")
    assert ramp_state(volume.pcvr) == saved


def test_ramp_survives_save_and_reload(tmp_path, volume):
    volume.pcvr.apply_preset("CT Cardiac")
    saved = ramp_state(volume.pcvr)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "scene.blend"))
    assert ramp_state(bpy.data.volumes["Box"].pcvr) == saved


def test_ramp_comes_along_when_the_volume_is_linked(tmp_path, volume):
    volume.pcvr.apply_preset("MR Default")
    saved = ramp_state(volume.pcvr)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "library.blend"))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    with bpy.data.libraries.load(str(tmp_path / "library.blend"), link=True) as (source, target):
        target.volumes = ["Box"]
    linked = bpy.data.volumes["Box"]
    assert linked.library is not None and linked.pcvr.transfer_function.library is not None
    assert ramp_state(linked.pcvr) == saved


def test_undo_restores_the_ramp(volume):
    volume.pcvr.ensure_transfer_function()
    bpy.ops.ed.undo_push(message="default")
    before = ramp_state(volume.pcvr)
    volume.pcvr.apply_preset("CT Bone")
    bpy.ops.ed.undo_push(message="bone")
    after = ramp_state(bpy.data.volumes["Box"].pcvr)
    bpy.ops.ed.undo()
    assert ramp_state(bpy.data.volumes["Box"].pcvr) == before
    bpy.ops.ed.redo()
    assert ramp_state(bpy.data.volumes["Box"].pcvr) == after
