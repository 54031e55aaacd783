"""Shadows in Blender (scene.pcvr.shadows, --shadows): two blobs in a row along a sun's light, seen from above; with
shadows on, the far one lies in the near one's shadow, for the lights whose Cast Shadow is on."""

import math

import bpy
import numpy as np
import pcvr_native as pn
import pytest

import blender_scenes as bs
import lit_scenes as ls
from pcvr_addon.render import statistics

# A sun travelling along +x: its -Z axis turned about Y.
SUN_ROTATION = (0.0, -math.pi / 2 + 0.1, 0.0)
NEAR, FAR = (-0.9, 0.0, 0.0), (0.9, 0.0, 0.0)
# Relative to the image's maximum: single-precision noise between Blender's numbers and the reference's.
TOLERANCE = 1e-5


@pytest.fixture
def blobs_in_a_row(tmp_path, rng):
    path = bs.write_vdb(tmp_path / "blob.vdb", bs.blob(rng))
    objects = [bs.add_volume(name, path, location=location) for name, location in (("Near", NEAR), ("Far", FAR))]
    for obj in objects:
        ls.set_ramp(obj)
    scene = ls.shaded_setup(96, 48)
    bs.add_camera(location=(0.0, 0.0, 3.0), ortho_scale=3.6)
    sun = ls.add_light('SUN', rotation=SUN_ROTATION, power=4.0)
    ls.set_world((0.0, 0.0, 0.0))
    return scene, objects, sun


def far_half(image):
    """The far blob's side of the image (x > 0: the right half)."""
    return image[:, image.shape[1] // 2:, :3]


def test_shadows_darken_the_far_blob_as_render_shaded_does(blobs_in_a_row):
    scene, objects, sun = blobs_in_a_row
    assert scene.pcvr.shadows is False  # off by default: images as before
    unshadowed = ls.combined(bs.render(scene))
    assert "Shadows" not in dict(statistics.statistics_rows(*statistics.last_render[scene.session_uid]))
    scene.pcvr.shadows = True
    shadowed = ls.combined(bs.render(scene))
    assert far_half(shadowed).mean() < 0.7 * far_half(unshadowed).mean()
    mode, stats = statistics.last_render[scene.session_uid]
    assert dict(statistics.statistics_rows(mode, stats))["Shadow texels"] == f"{stats['shadow_texels']:,}"
    # The same call made directly: the sun at strength 4 / pi (docs/shaded-rendering-in-blender.md).
    light = pn.Light.sun(ls.sun_direction(SUN_ROTATION), strength=4.0 / math.pi)
    reference = pn.render_shaded([bs.world_grid(obj) for obj in objects], bs.reference_camera(),
                                 ls.reference_transfer_function(), lights=[light], ambient=(0.0, 0.0, 0.0),
                                 method="regular", shading=pn.Shading(), shadows=True)
    assert np.abs(shadowed - reference).max() <= TOLERANCE * reference.max()


def test_a_light_that_casts_no_shadow_is_not_attenuated(blobs_in_a_row):
    scene, _objects, sun = blobs_in_a_row
    unshadowed = ls.combined(bs.render(scene))
    scene.pcvr.shadows = True
    sun.data.use_shadow = False
    assert np.array_equal(ls.combined(bs.render(scene)), unshadowed)


def test_a_suns_angle_softens_its_shadow_as_render_shaded_does(blobs_in_a_row):
    scene, objects, sun = blobs_in_a_row
    scene.pcvr.shadows = True
    sun.data.angle = 0.4  # radians: Blender's sun Angle, the disc's angular diameter
    soft = ls.combined(bs.render(scene))
    light = pn.Light.sun(ls.sun_direction(SUN_ROTATION), strength=4.0 / math.pi, angle=sun.data.angle)
    reference = pn.render_shaded([bs.world_grid(obj) for obj in objects], bs.reference_camera(),
                                 ls.reference_transfer_function(), lights=[light], ambient=(0.0, 0.0, 0.0),
                                 method="regular", shading=pn.Shading(), shadows=True)
    assert np.abs(soft - reference).max() <= TOLERANCE * reference.max()
    sun.data.angle = 0.0
    hard = ls.combined(bs.render(scene))
    assert np.abs(soft - hard).max() > 0.01 * hard.max()  # the angle reached the shadows
