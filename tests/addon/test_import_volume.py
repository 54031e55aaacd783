"""File > Import > PCVR Volume: the scan as a volume object, placed where the data says in scene units,
with its modality's preset; errors reported, nothing imported."""

import bpy
import numpy as np
import pytest

import scan_files as sf
from pcvr_addon.io import import_volume

ROW = np.array([0.0, 1.0, 0.0])      # a sagittal-ish series: rows along +y, columns down -z
COLUMN = np.array([0.0, 0.0, -1.0])
NORMAL = np.cross(ROW, COLUMN)
ORIGIN = np.array([40.0, -120.0, 300.0])
PIXEL_SPACING = (0.5, 0.75)


def ct_files(folder, rng, modality="CT"):
    stored = rng.integers(-1024, 2000, size=(4, 5, 6)).astype(np.int16)
    files = sf.dicom_series(str(folder), stored, origin=ORIGIN, row_direction=ROW, column_direction=COLUMN,
                            pixel_spacing=PIXEL_SPACING, step=2.0 * NORMAL, intercept=-1024.0, modality=modality)
    return stored, files


def test_menu_entry_names_the_formats():
    assert "DICOM, NIfTI, NRRD, MetaImage, TIFF" in import_volume.MENU_LABEL
    assert hasattr(bpy.types, "PCVR_OT_import_volume")


def test_ct_series_lands_at_its_patient_position_in_metres_with_a_ct_preset(tmp_path, rng):
    _, files = ct_files(tmp_path / "ct", rng)
    assert bpy.ops.pcvr.import_volume(filepath=files[2], unit_scale=0.001,
                                      directory_for_vdb=str(tmp_path / "vdb")) == {'FINISHED'}
    obj = bpy.context.view_layer.objects.active
    assert obj.type == 'VOLUME' and tuple(obj.scale) == pytest.approx((0.001,) * 3)
    volume = obj.data
    volume.grids.load()
    grid = volume.grids["density"]
    to_world = np.array(obj.matrix_world) @ np.array(grid.matrix_object)
    for s, r, c in [(0, 0, 0), (3, 4, 5), (1, 2, 3)]:
        patient_mm = ORIGIN + s * 2.0 * NORMAL + c * PIXEL_SPACING[1] * ROW + r * PIXEL_SPACING[0] * COLUMN
        # Blender's matrices are float32: about 1e-7 of the 0.3 m positions.
        np.testing.assert_allclose(sf.world(to_world, (s, r, c)), patient_mm * 0.001, atol=1e-6)
    assert (volume.pcvr.tf_min, volume.pcvr.tf_max) == (-3024.0, 3071.0)  # CT Bone's range
    assert volume["pcvr_modality"] == "CT" and volume["pcvr_units"] == "HU"


def test_mr_gets_mr_default_and_no_preset_when_asked(tmp_path, rng):
    _, files = ct_files(tmp_path / "mr", rng, modality="MR")
    bpy.ops.pcvr.import_volume(filepath=files[0], directory_for_vdb=str(tmp_path / "vdb"))
    imported = bpy.context.view_layer.objects.active.data
    reference = bpy.data.volumes.new("reference")
    reference.pcvr.apply_preset("MR Default")
    assert (imported.pcvr.tf_min, imported.pcvr.tf_max) == (reference.pcvr.tf_min, reference.pcvr.tf_max)
    assert not imported.pcvr.use_grid_range

    bpy.ops.pcvr.import_volume(filepath=files[0], apply_preset=False, directory_for_vdb=str(tmp_path / "vdb"))
    assert bpy.context.view_layer.objects.active.data.pcvr.use_grid_range  # the default, untouched


def test_a_bad_scan_is_reported_and_nothing_is_imported(tmp_path, rng):
    _, files = ct_files(tmp_path / "ct", rng)
    (tmp_path / "ct" / files[1].split("/")[-1]).unlink()  # a slice missing in the middle
    with pytest.raises(RuntimeError, match=r"slice\(s\) missing"):
        bpy.ops.pcvr.import_volume(filepath=files[0], directory_for_vdb=str(tmp_path / "vdb"))
    assert len(bpy.data.objects) == 0 and len(bpy.data.volumes) == 0


def test_beside_a_saved_blend_the_vdb_is_kept_with_it_by_a_relative_path(tmp_path, rng):
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"))
    _, files = ct_files(tmp_path / "ct", rng)
    bpy.ops.pcvr.import_volume(filepath=files[0])
    volume = bpy.context.view_layer.objects.active.data
    assert volume.filepath.startswith("//pcvr_volumes/") and volume.filepath.endswith("ct_volume.vdb")
    assert (tmp_path / volume.filepath[2:]).is_file()
