"""pcvr.c_arm_view: the scene camera made a C-arm's, so that F12 renders what pn.render_xray renders through
pn.cameras.cone_beam for the same geometry, in a scene of a millimetre a unit and in one of a metre a unit."""

import bpy
import numpy as np
import pcvr_native as pn
import pytest
from pcvr_native.cameras import cone_beam

import blender_scenes as bs

# Millimetres and degrees, as the operator takes them: an off-centre, non-square detector seen obliquely.
C_ARM = dict(sad=300.0, sid=500.0, detector_cols=48, detector_rows=40, pixel_spacing=(1.5, 1.2), gantry=30.0,
             tilt=10.0, detector_offset=(4.0, -3.0))
VOXEL_MM = 2.0


def _c_arm_camera(c_arm, isocentre_mm, unit):
    """cone_beam of the operator's settings `c_arm` in world units of `unit` per millimetre."""
    return cone_beam(c_arm["sad"] * unit, c_arm["sid"] * unit, (c_arm["detector_cols"], c_arm["detector_rows"]),
                     np.multiply(c_arm["pixel_spacing"], unit), np.multiply(isocentre_mm, unit), c_arm["gantry"],
                     c_arm["tilt"], np.multiply(c_arm["detector_offset"], unit))


# A wide detector (Blender's sensor fit horizontal) in a scene of a millimetre a unit, and a tall one (vertical fit)
# in a scene of a metre a unit.
@pytest.mark.parametrize("scale_length, object_scale, detector", [(0.001, 1.0, (48, 40)), (1.0, 0.001, (30, 44))])
def test_f12_renders_the_cone_beam_view(tmp_path, scale_length, object_scale, detector):
    # A lumpy volume of 2 mm voxels whose active voxels centre at (10, -5, 20) mm: as the command line places a scan
    # (a unit a millimetre) and as File > Import does (a metre a unit, the object scaled by 0.001).
    path = bs.write_vdb(tmp_path / "blob.vdb", bs.blob(np.random.default_rng(3)), bs.centred(VOXEL_MM))
    obj = bs.add_volume("Blob", path, location=np.multiply((10.0, -5.0, 20.0), object_scale),
                        scale=(object_scale,) * 3)
    bpy.context.view_layer.objects.active = obj
    scene = bs.setup(method='PCVR', passband='COMPENSATED')
    scene.unit_settings.scale_length = scale_length
    c_arm = dict(C_ARM, detector_cols=detector[0], detector_rows=detector[1])
    assert 'FINISHED' in bpy.ops.pcvr.c_arm_view(**c_arm)

    camera = scene.camera
    assert camera.data.type == 'PERSP'
    assert (scene.render.resolution_x, scene.render.resolution_y) == detector
    unit = 0.001 / scale_length  # world units per millimetre
    grid = bs.world_grid(obj)
    lo, hi = np.asarray(grid.index_bbox, dtype=np.float64)
    isocentre_mm = (grid.index_to_world @ np.append((lo + hi) / 2, 1.0))[:3] / unit
    np.testing.assert_allclose(isocentre_mm, (10.0, -5.0, 20.0), atol=1e-3)
    expected = pn.render_xray(grid, _c_arm_camera(c_arm, isocentre_mm, unit))
    # Blender's camera matrices are single precision: measured 6e-5 and 7e-5 of the peak apart.
    bs.assert_matches(bs.xray(bs.render(scene)), expected, tolerance=1e-3)


def test_isocentre_can_be_given(tmp_path):
    path = bs.write_vdb(tmp_path / "box.vdb", bs.box(), bs.centred(VOXEL_MM))
    bpy.context.view_layer.objects.active = bs.add_volume("Box", path)
    scene = bs.setup()
    scene.unit_settings.scale_length = 0.001
    bpy.ops.pcvr.c_arm_view(sad=400.0, sid=600.0, gantry=90.0, use_isocentre=True, isocentre=(0.0, 7.0, -2.0))
    # Gantry 90: the source at +x of the isocentre, looking along -x.
    np.testing.assert_allclose(scene.camera.matrix_world.translation, (400.0, 7.0, -2.0), atol=1e-4)
    np.testing.assert_allclose(np.array(scene.camera.matrix_world)[:3, 2], (1.0, 0.0, 0.0), atol=1e-6)


def test_bad_geometry_is_reported(tmp_path):
    path = bs.write_vdb(tmp_path / "box.vdb", bs.box(), bs.centred(VOXEL_MM))
    bpy.context.view_layer.objects.active = bs.add_volume("Box", path)
    with pytest.raises(RuntimeError, match=r"sid 500.0\) must exceed"):
        bpy.ops.pcvr.c_arm_view(sad=600.0, sid=500.0)
    with pytest.raises(RuntimeError, match="not a volume"):
        bpy.context.view_layer.objects.active = None
        bpy.ops.pcvr.c_arm_view()
