"""Emission in shaded rendering: TransferFunction(..., emission=[[r, g, b], ...]).

A sample of extinction sigma and emission e (radiance per world unit) over a stretch L of ray sends
e (1 - exp(-sigma L)) / sigma out of its front (e L where sigma is 0), attenuated by what lies in front.
The tests hold it to integrals known in closed form:

* Emission only (no opacity): the colour is e times the line integral of the emission profile, so a
  transfer function with emission e * density renders e times the X-ray image; a slab of constant
  density d, t world units thick, shows e d t at its centre.
* Absorption only: a slab of extinction k d shows the opacity 1 - exp(-k d t).
* Both, with extinction k * density and emission e * density: along any ray the light is
  (e / k) (1 - exp(-k D)) for the ray's integral D, that is (e / k) times the alpha, whatever the
  profile: the per-sample terms telescope, so it holds for every sheet spacing and method.
"""

from __future__ import annotations

import numpy as np
import pytest

import pcvr_native as pn

from conftest import REGULAR_TOL, frame_ortho
from shaded_scenes import SUN, blob_volume, camera, psnr

K = 2.0  # extinction per unit density per world unit
GLOW = np.array([0.6, 0.3, 0.1])  # emission per unit density per world unit
VOXEL = 0.1
DEPTH = 12  # voxels: the slab is 1.2 world units thick


def slab(value: float = 1.0) -> pn.Grid:
    """A constant slab, 24 x 24 voxels across and DEPTH deep, seen face-on along -z."""
    values = np.full((24, 24, DEPTH), value, dtype=np.float32)
    return pn.Grid.from_dense(values, np.diag([VOXEL, VOXEL, VOXEL, 1.0]))


def glowing_tf(k: float = 0.0, top: float = 3.0, unit_distance: float = 0.05, points: int = 400) -> pn.TransferFunction:
    """Black, extinction k * density (k = 0: no opacity at all), emission GLOW * density."""
    d = np.linspace(0.0, top, points)
    alpha = 1.0 - np.exp(-k * d * unit_distance)
    return pn.TransferFunction(density=d, rgba=[[0.0, 0.0, 0.0, a] for a in alpha], unit_distance=unit_distance,
                               emission=np.outer(d, GLOW))


def render(grid, cam, tf, method, **kw):
    kw.setdefault("opacity_cutoff", 1.0)
    if method == "raycast":  # a tenth of a voxel: its midpoint rule then matches the splats' slab integrals
        kw.setdefault("sheet_spacing", 0.1)
    return pn.render_shaded(grid, cam, tf, lights=[], ambient=(0, 0, 0), method=method, **kw).astype(np.float64)


def centre(image):
    h, w = image.shape[:2]
    return image[h // 2, w // 2]


@pytest.mark.parametrize("method", ["regular", "pcvr", "raycast"])
def test_an_emission_only_slab_glows_by_its_thickness(method):
    grid = slab(1.0)
    cam = frame_ortho(grid, 2.0).camera()
    image = render(grid, cam, glowing_tf(), method)
    # The slab's interior integrates to d t to the kernel's partition-of-unity ripple (render_xray
    # measures 1.2011 for 1.2 here): measured 9.3e-4 to 9.6e-4 relative for every method.
    np.testing.assert_allclose(centre(image)[:3], GLOW * 1.0 * DEPTH * VOXEL, rtol=2e-3)
    assert centre(image)[3] == 0.0  # nothing absorbs
    assert np.all(image[..., 3] == 0.0)


@pytest.mark.parametrize("method", ["regular", "pcvr"])
def test_emission_alone_renders_the_xray_image_times_the_emission(method):
    """The sheets sum to the X-ray (test_shaded_identities); so does the light they emit."""
    grid = blob_volume(20)
    cam = camera(grid, "persp", 2.5)
    image = render(grid, cam, glowing_tf(), method, samples_per_sheet=1, stride=2, post_filter="gauss1.4")
    # The sheets are the paper's pipeline: the X-ray's passband compensation (its default) is not theirs.
    xray = pn.render_xray(grid, cam, method=method, stride=2, post_filter="gauss1.4", passband="paper").astype(np.float64)
    for c in range(3):  # measured 3.5e-5 of the peak (regular)
        assert np.abs(image[..., c] - GLOW[c] * xray).max() <= REGULAR_TOL * GLOW[c] * xray.max()


@pytest.mark.parametrize("method", ["pcvr", "raycast"])
def test_an_absorption_only_slab_has_the_beer_lambert_opacity(method):
    grid = slab(1.0)
    cam = frame_ortho(grid, 2.0).camera()
    tf = glowing_tf(k=K)
    tf = pn.TransferFunction(density=tf.density, rgba=tf.rgba, unit_distance=tf.unit_distance)  # no emission
    image = render(grid, cam, tf, method)
    # The optical depth is k d t to the kernel's ripple, as above (measured 9.3e-4 to 1.0e-3 relative).
    assert -np.log1p(-centre(image)[3]) / K == pytest.approx(DEPTH * VOXEL, rel=2e-3)
    assert np.all(image[..., :3] == 0.0)


@pytest.mark.parametrize("method", ["regular", "pcvr", "raycast"])
@pytest.mark.parametrize("spacing, samples", [(1.0, 1), (0.5, 2)])
def test_emitted_light_is_glow_over_extinction_times_alpha(method, spacing, samples):
    """Extinction k d and emission e d: light (e / k) alpha on every ray, whatever the density profile."""
    grid = blob_volume(20)
    cam = camera(grid, "persp", 2.0)
    image = render(grid, cam, glowing_tf(k=K), method, sheet_spacing=spacing, samples_per_sheet=samples)
    alpha = image[..., 3]
    seen = alpha > 1e-3
    assert seen.sum() > 100
    for c in range(3):
        # Measured at most 1.6e-5 of e / k (float rounding of the opacities and of the table).
        assert np.abs(image[..., c] - GLOW[c] / K * alpha).max() <= 1e-4 * GLOW[c] / K


def test_an_emitting_lit_blob_matches_the_ray_caster():
    grid = blob_volume(24)
    cam = camera(grid, "ortho", 2.0)
    d = np.linspace(0.0, 1.0, 5)
    tf = pn.TransferFunction(density=d, rgba=[[0.9, 0.8, 0.7, a] for a in (0, 0.02, 0.1, 0.3, 0.5)],
                             emission=[[0, 0, 0], [0.5, 0.2, 0.0], [2.0, 0.8, 0.1], [3.0, 2.0, 0.5], [4.0, 3.0, 1.0]])
    kw = dict(lights=[SUN], ambient=(0.1, 0.1, 0.1))
    reference = pn.render_shaded(grid, cam, tf, method="raycast", sheet_spacing=0.1, **kw)
    image = pn.render_shaded(grid, cam, tf, method="pcvr", **kw)
    assert float(np.max(reference[..., 0])) > 0.3  # the emission dominates, and is bright
    # Measured 47.9 dB; less 2 dB as in test_shaded_accuracy.
    assert psnr(np.clip(image, 0, 1), np.clip(reference, 0, 1)) > 45.9


@pytest.mark.parametrize("method", ["pcvr", "raycast"])
def test_zero_emission_changes_nothing(method):
    grid = blob_volume(20)
    cam = camera(grid, "persp", 2.0)
    d = [0.0, 0.3, 1.0]
    rgba = [[0, 0, 0, 0], [0.8, 0.4, 0.3, 0.1], [1, 1, 1, 0.6]]
    plain = pn.render_shaded(grid, cam, pn.TransferFunction(density=d, rgba=rgba), lights=[SUN], method=method)
    zero = pn.render_shaded(grid, cam, pn.TransferFunction(density=d, rgba=rgba, emission=[[0, 0, 0]] * 3),
                            lights=[SUN], method=method)
    assert np.array_equal(plain, zero)


def test_emitting_blocks_are_not_culled_as_transparent():
    """An emission-only volume has no opacity anywhere: culling by opacity alone would drop all of it.
    Two blobs, one bright (peak 1) and one faint (0.1), below the 0.3 where emission starts: the faint
    one's blocks go, the bright one's stay, and the image is what it is without culling."""
    i, j, k = np.mgrid[:64, :16, :16]
    values = sum(peak * np.exp(-((i - at) ** 2 + (j - 7.5) ** 2 + (k - 7.5) ** 2) / (2 * 2.5**2)) for at, peak in ((8, 1.0), (56, 0.1)))
    values[values < 1e-3] = 0  # inactive: the blobs' blocks apart
    grid = pn.Grid.from_dense(values.astype(np.float32), np.diag([VOXEL, VOXEL, VOXEL, 1.0]))
    cam = camera(grid, "ortho", 2.0)
    tf = pn.TransferFunction(density=[0.0, 0.3, 1.0], rgba=[[0, 0, 0, 0]] * 3, emission=[[0, 0, 0], [0, 0, 0], [1, 0.5, 0.2]])
    stats = {}
    culled = pn.render_shaded(grid, cam, tf, cull_transparent=True, stats=stats)
    kept = pn.render_shaded(grid, cam, tf, cull_transparent=False)
    assert culled[..., 0].max() > 0.3
    assert 0 < stats["blocks_transparent"] < stats["blocks"]  # measured 8 of 20
    assert np.array_equal(culled, kept)


def test_emission_reads_back():
    tf = pn.TransferFunction(density=[0, 1], rgba=[[0, 0, 0, 0], [1, 1, 1, 1]], emission=[[0, 0, 0], [1, 2, 3]])
    assert tf.emission == [(0.0, 0.0, 0.0), (1.0, 2.0, 3.0)]
    assert pn.TransferFunction(density=[0, 1], rgba=[[0, 0, 0, 0], [1, 1, 1, 1]]).emission == []


@pytest.mark.parametrize("emission, message", [
    ([[0, 0, 0]], "2 densities but 1 emission"),
    ([[0, 0], [1, 1]], "emission must be a list of [r, g, b] rows"),
    ([[0, 0, 0], [-1, 0, 0]], "control point 1: emission must be finite and not negative"),
    ([[0, 0, 0], [np.nan, 0, 0]], "control point 1: emission must be finite and not negative"),
    ([[0, 0, 0], [np.inf, 0, 0]], "control point 1: emission must be finite and not negative"),
])
def test_bad_emission_is_named(emission, message):
    with pytest.raises(ValueError, match=f"TransferFunction: .*{message.replace('[', '.').replace(']', '.')}"):
        pn.TransferFunction(density=[0, 1], rgba=[[0, 0, 0, 0], [1, 1, 1, 1]], emission=emission)
