"""Ambient occlusion (pn.Shading(ambient_occlusion=True)): the ambient light reaches each sample through the
volumes, as the world's light does in Cycles: times the mean of its transmittance towards +-x, +-y and +-z.
The sheet renderers read it from six light volumes (src/shaded/light/light_volume.h, at twice the shadows' texel
spacing), the ray caster casts the six shadow rays at every sample: it is the judge."""

from __future__ import annotations

import numpy as np
import pytest

import pcvr_native as pn

from shaded_scenes import SUN, camera, ct_volume, psnr
from shadow_scenes import REFERENCE_SPACING

# The CT phantom's brain faintly red, its skull nearly opaque: the brain sits in the skull's shadow from every side.
TF = pn.TransferFunction(density=[0.0, 0.15, 0.25, 1.0], rgba=[[0, 0, 0, 0], [0.8, 0.5, 0.4, 0.0], [0.8, 0.5, 0.4, 0.3], [1, 1, 1, 0.9]])
AMBIENT = (0.6, 0.6, 0.6)  # a bright world, so that its occlusion shows


@pytest.fixture(scope="module")
def ct():
    return ct_volume(24)


STEP = 5  # the ray caster's pixels: six shadow rays per sample make it the slow part


def renders(ct, model: str, occlusion: bool):
    """pcvr's image at the ray caster's pixels, and the ray caster's."""
    # Blinn-Phong's ambient coefficient as high as scattering's (which takes the ambient colour whole).
    # One octave: the occlusion of light scattered once (the octaves give some back: test_multiple_scattering.py).
    kw = dict(lights=[SUN], ambient=AMBIENT, opacity_cutoff=1.0,
              shading=pn.Shading(model=model, ambient=0.6, ambient_occlusion=occlusion, scattering_octaves=1))
    cam = camera(ct, "persp", 3.0)
    image = pn.render_shaded(ct, cam, TF, **kw)
    reference = pn.render_shaded(ct, cam, TF, method="raycast", sheet_spacing=REFERENCE_SPACING, pixel_step=STEP, **kw)
    return image[::STEP, ::STEP], reference


# Measured PSNR (dB) of pcvr against the ray caster, without and with occlusion: Blinn-Phong 37.6 and 37.3,
# scattering 53.3 and 43.5 (the occlusion volumes' texels are two voxels apart; the ray caster steps a quarter
# voxel). The thresholds sit 2 dB below; the occlusion itself moves the ray caster's image by 25.9 and 21.5 dB,
# and takes 30% and 57% of pcvr's light.
@pytest.mark.parametrize("model, least_psnr", [("blinn_phong", 35.0), ("scatter", 41.5)])
def test_occluded_ambient_light_matches_the_ray_caster(ct, model, least_psnr):
    lit, reference = renders(ct, model, True)
    plain, plain_reference = renders(ct, model, False)
    assert psnr(lit, reference) >= least_psnr
    assert psnr(reference, plain_reference) < 27.0
    # Only light is taken away: no pixel brightens, and the phantom's inside darkens.
    assert np.all(lit[..., :3] <= plain[..., :3] + 1e-4)
    assert lit[..., :3].mean() < 0.8 * plain[..., :3].mean()
    assert np.array_equal(lit[..., 3], plain[..., 3])  # opacity is the transfer function's alone


def test_occlusion_is_off_by_default_and_costs_light_volumes(ct):
    assert pn.Shading().ambient_occlusion is False
    cam = camera(ct, "persp", 2.0)
    off, on = {}, {}
    pn.render_shaded(ct, cam, TF, lights=[SUN], stats=off)
    pn.render_shaded(ct, cam, TF, lights=[SUN], shading=pn.Shading(ambient_occlusion=True), stats=on)
    assert off["shadow_texels"] == 0 < on["shadow_texels"]


def test_unlit_volumes_ignore_occlusion(ct):
    cam = camera(ct, "ortho", 2.0)
    plain = pn.render_shaded(ct, cam, TF, shading=pn.Shading(lit=False))
    occluded = pn.render_shaded(ct, cam, TF, shading=pn.Shading(lit=False, ambient_occlusion=True))
    assert np.array_equal(plain, occluded)
