"""Single scattering (pn.Shading(model="scatter", anisotropy=g)): the transfer function's colour is the albedo,
lit by the ambient colour and by each light through the Henyey-Greenstein phase function, normalised over the
sphere as in Cycles' Principled Volume; no normals."""

from __future__ import annotations

import math

import numpy as np
import pytest

import pcvr_native as pn

from cloud_scenes import white_cloud_tf
from shaded_scenes import SUN, bone_tf, camera, ct_volume, point_light, psnr
from shadow_scenes import pcvr_and_reference

ALBEDO = np.array([0.9, 0.6, 0.3])


def henyey_greenstein(g: float, cos_theta: float) -> float:
    return (1 - g * g) / (4 * math.pi * (1 + g * g - 2 * g * cos_theta) ** 1.5)


def uniform_slab() -> pn.Grid:
    values = np.zeros((24, 24, 8), dtype=np.float32)
    values[:, :, 2:6] = 0.5
    return pn.Grid.from_dense(values, np.eye(4))


@pytest.mark.parametrize("method", ["pcvr", "raycast"])
@pytest.mark.parametrize("g", [0.0, 0.6, -0.4])
def test_a_uniform_albedo_scatters_by_the_phase_function(method, g):
    """Seen along -z, lit by a sun travelling (0.3, 0, 0.8): every sample has radiance albedo * (ambient + pi E
    p(cos theta)), pi E the sun's irradiance, cos theta between the light's travel and the way to the eye (+z), so
    a pixel's colour over its alpha is that, to float rounding (measured: 5e-7 relative at most)."""
    grid = uniform_slab()
    cam = camera(grid, "ortho", 1.0, direction=(0, 0, -1))
    tf = pn.TransferFunction(density=[0.0, 1.0], rgba=[[*ALBEDO, 0.0], [*ALBEDO, 0.6]])
    travel = np.array([0.3, 0.0, 0.8])
    sun = pn.Light.sun(direction=travel, color=(1.0, 0.8, 0.6), strength=3.0)
    ambient = np.array([0.05, 0.1, 0.2])
    image = pn.render_shaded(grid, cam, tf, lights=[sun], ambient=ambient, method=method,
                             shading=pn.Shading(model="scatter", anisotropy=g), opacity_cutoff=1.0)
    seen = image[..., 3] > 0.2
    cos_theta = travel[2] / np.linalg.norm(travel)
    expected = ALBEDO * (ambient + math.pi * 3.0 * np.array([1.0, 0.8, 0.6]) * henyey_greenstein(g, cos_theta))
    colour = image[seen, :3] / image[seen, 3:]
    assert seen.sum() > 100
    assert np.allclose(colour, expected, rtol=1e-5), (colour.min(axis=0), colour.max(axis=0), expected)


# scene -> minimum PSNR against the ray caster (measured less 2 dB), shadows on. The lights are 4 times as strong
# as Blinn-Phong's scenes': scattering turns strength E into irradiance pi E, which an isotropic phase function
# spreads over the sphere's 4 pi (the images are those measured before lights scattered pi E, at 4 pi E).
SCENES = {"ct-ortho-sun": 37.2, "ct-persp-point": 37.3}
BRIGHTER = 4.0


@pytest.mark.parametrize("name", list(SCENES))
def test_against_the_ray_caster(name):
    grid = ct_volume(32)
    projection, light = name.split("-")[1:]
    light = SUN if light == "sun" else point_light(grid)
    kind = pn.Light.sun if light.kind == "sun" else pn.Light.point
    lights = [kind(light.vector, strength=light.strength * BRIGHTER)]
    scatter = pn.Shading(model="scatter", anisotropy=0.4, scattering_octaves=1)  # octaves: test_multiple_scattering.py
    image, reference = pcvr_and_reference(grid, camera(grid, projection, 3.0), bone_tf(), lights, shading=scatter,
                                          shadows=True, ambient=(0.2, 0.2, 0.2))
    assert psnr(image, reference) >= SCENES[name], psnr(image, reference)


def thin_slab(extinction: float):
    """A slab 4 voxels thick in z (trilinear: 0, v, v, v, v, 0 integrates to 4 v), white, of optical depth
    4 * extinction across, wide enough that its middle pixels see no edge."""
    values = np.zeros((40, 40, 8), dtype=np.float32)
    values[:, :, 2:6] = 1.0
    return pn.Grid.from_dense(values, np.eye(4)), white_cloud_tf(extinction, albedo=1.0), 4 * extinction


# method -> (render_shaded's arguments, relative tolerance). Measured: the sheets
# 2e-5 off, the ray caster 0.6% (its alpha as much below 1 - exp(-tau)), the path tracer (256 paths a pixel;
# always shadowed, and it scatters more than once) 3% above, its noise 1.3% over the middle pixels.
SLAB_METHODS = {"pcvr": ({}, 1e-3), "raycast": ({}, 0.02),
                "paths": (dict(method="raycast", paths=256, seed=1, shadows=True), 0.1)}


@pytest.mark.parametrize("method", list(SLAB_METHODS))
def test_a_sun_of_strength_e_scatters_as_irradiance_pi_e(method):
    """Lights' strength E is Blinn-Phong's (a white diffuse surface facing the sun shows kd E), which makes the
    sun's irradiance pi E (Lambert's law): scattering receives that. A thin white slab (optical depth tau = 0.04),
    the sun behind the camera, isotropic: each pixel's radiance is pi E p (1 - exp(-tau)), about pi E tau / (4 pi)
    (p = 1 / (4 pi)), as Cycles' Principled Volume has it; 1/pi of that before issue 39's follow-up."""
    grid, tf, tau = thin_slab(0.01)
    kwargs, tolerance = SLAB_METHODS[method]
    kwargs = {"method": method, **kwargs}
    strength = 2.0
    image = pn.render_shaded(grid, camera(grid, "ortho", 1.0, direction=(0, 0, -1)), tf,
                             lights=[pn.Light.sun(direction=(0, 0, -1), strength=strength)], ambient=(0, 0, 0),
                             opacity_cutoff=1.0, shading=pn.Shading(model="scatter"), **kwargs)
    h, w = image.shape[:2]
    middle = image[h // 4:3 * h // 4, w // 4:3 * w // 4].astype(np.float64)
    expected = math.pi * strength * henyey_greenstein(0.0, 1.0) * (1 - math.exp(-tau))
    assert abs(middle[..., :3].mean() / expected - 1) < tolerance, (middle[..., :3].mean(), expected)


def test_bad_scattering_parameters_are_named():
    with pytest.raises(ValueError, match="unknown model 'mie'"):
        pn.Shading(model="mie")
    for g in (1.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="anisotropy must lie strictly between -1 and 1"):
            pn.Shading(model="scatter", anisotropy=g)
    s = pn.Shading(model="scatter", anisotropy=0.3)
    assert (s.model, s.anisotropy) == ("scatter", 0.3)
    assert pn.Shading().model == "blinn_phong"
