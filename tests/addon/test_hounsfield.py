"""X-ray of a CT in Hounsfield units through Blender: Volume Properties > PCVR > X-Ray Values, the scene's unit."""

import bpy
import numpy as np
import pcvr_native as pn
import pytest

import blender_scenes as bs
from pcvr_addon.render.passes import EXPOSURE_GREY


@pytest.fixture
def ct_object(tmp_path):
    values = np.full((16, 16, 16), -1000.0, np.float32)   # air
    values[3:13, 3:13, 3:13] = 40.0                       # soft tissue
    values[6:10, 6:10, 6:10] = 1200.0                     # bone
    values[4:6, 4:6, 4:6] = -800.0                        # lung-like air inside: the map sends it to 0.2 mu_water
    path = tmp_path / "ct.vdb"
    pn.Grid.from_dense(values, bs.centred(), background=-1000.0).write_vdb(str(path))
    obj = bs.add_volume("CT", str(path))
    bpy.context.view_layer.objects.active = obj
    return obj


@pytest.mark.parametrize("scale_length, mu_water", [(1.0, 0.193), (0.001, 0.25)])
def test_drr_integrates_attenuation_in_the_scenes_unit(ct_object, scale_length, mu_water):
    scene = bs.setup()
    bpy.ops.pcvr.frame_volume(magnification=2.0, view='ISO')
    scene.unit_settings.scale_length = scale_length
    settings = ct_object.data.pcvr
    raw = bs.xray(bs.render(scene))
    assert raw.min() < 0  # Hounsfield units integrated as they are: rays through the pocket below zero

    settings.xray_values, settings.mu_water = 'HOUNSFIELD', mu_water
    drr = bs.xray(bs.render(scene))
    per_unit = mu_water * 100.0 * scale_length  # per centimetre -> per scene unit
    reference = pn.render_xray(bs.world_grid(ct_object), bs.reference_camera(), method="exact",
                               attenuation=pn.AttenuationMap.hounsfield(per_unit))
    bs.assert_matches(drr, reference)
    assert drr.min() >= 0


def test_automatic_exposure(ct_object):
    """Automatic exposure picks the gain from the image: the brightest percent of the volume's pixels at 80% grey
    in the Combined pass, whatever the scale of the integrals; the XRay pass stays the raw integral."""
    scene = bs.setup()
    bpy.ops.pcvr.frame_volume(magnification=2.0, view='FRONT')
    ct_object.data.pcvr.xray_values = 'HOUNSFIELD'
    scene.pcvr.use_auto_exposure = True
    for scale_length in (1.0, 0.001):  # integrals 1000 times apart
        scene.unit_settings.scale_length = scale_length
        passes = bs.render(scene)
        integral, grey = bs.xray(passes), passes["ViewLayer.Combined"][:, :, 0]
        reached = integral > 0
        assert np.percentile(grey[reached], 99) == pytest.approx(EXPOSURE_GREY, abs=0.01)
        assert grey[~reached].max() == 0.0
