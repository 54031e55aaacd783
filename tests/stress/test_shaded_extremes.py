"""Shaded and MIP rendering under stress: scales from 1e-12 to 1e9 world units and volumes 1e8 units
out, opacity that saturates within a few sheets, densities near float32's range, the eye inside the
volume, and thread counts.

The transfer function's opacity is per `unit_distance`, which defaults to the grid's voxel size, so
optical depths, and hence the image, do not change with scale. Measured (48 x 48, the 24^3 CT
phantom, lit by a sun and a point light): at the origin the scaled scene's image matches the unit one to 1.1e-5 of its
peak at every scale from 1e-12 to 1e9 (float32 rounding; 1.8e-6 with sheets splatted rather than sampled; before the shading normalised gradients by
their largest component and took its frame relative to the camera, 1e-12 was 40% off, unlit). 1e8
units out, positions are resolved to |offset| x 2.2e-16 as for X-ray (tests/stress/test_scale.py), and
the shaded image, whose sharp opaque edges and point light turn a shift into a change of colour, moves
by up to 21.8 times that resolution in voxels (1.4 times orthographically)."""

import numpy as np
import pytest

import pcvr_native as pn
from pcvr_native import cameras, phantoms

from stress_helpers import LONG, max_error, placed, resolution_in_voxels, scene_camera

CT = phantoms.ct_phantom(24)
# The phantom spans [-1, 1]; scene_camera frames [-10, 10] at unit scale.
UNIT_PLACEMENT = np.diag([8.0, 8.0, 8.0, 1.0]) @ np.asarray(CT.index_to_world)
SUN = pn.Light.sun(direction=(-0.5, -0.2, -0.8))
BONE = pn.TransferFunction(density=[0.0, 0.3, 0.6, 1.0],
                           rgba=[[0, 0, 0, 0], [0.8, 0.4, 0.3, 0.0], [0.9, 0.8, 0.6, 0.4], [1, 1, 1, 0.9]])
# Twice the largest measured at the origin: 1.07e-5 with sheets sampled (the default at this magnification:
# positions along perspective rays from the eye in float, their spacing from rsqrt8; 9.1e-6 with a square root
# and a division), 1.8e-6 splatted (3.2e-6 before sessions 4-6).
FLOAT32_ROUNDING = 2.2e-5
PER_RESOLUTION = 32.0      # 1.5 times the largest measured error per voxel of position resolution (21.8)
SCALES = [(1e-12, 0.0), (1e-9, 0.0), (1e-6, 0.0), (1e-3, 0.0), (1e3, 0.0), (1e9, 0.0), (1e-3, 1e8), (1.0, 1e8)]


def ct_grid(scale=1.0, offset=(0.0, 0.0, 0.0), values=None):
    return pn.Grid.from_dense(CT.values if values is None else values, placed(scale, offset) @ UNIT_PLACEMENT)


def lights(scale=1.0, offset=(0.0, 0.0, 0.0)):
    """The sun and a point light up and to the left, as bright at the volume at every scale."""
    lamp = pn.Light.point(position=np.array([-6.0, 8.0, 5.0]) * scale + offset, strength=125.0 * scale ** 2)
    return [SUN, lamp]


@pytest.fixture(scope="module")
def unit_images():
    return {persp: pn.render_shaded(ct_grid(), scene_camera(1.0, 0.0, persp), BONE, lights=lights()) for persp in (False, True)}


@pytest.mark.parametrize("persp", [False, True], ids=["ortho", "persp"])
@pytest.mark.parametrize("scale,offset", SCALES if LONG else SCALES[1::2])
def test_scaled_scene_shades_as_the_unit_scene(unit_images, scale, offset, persp):
    where = np.array([1.0, -0.5, 0.25]) * offset
    image = pn.render_shaded(ct_grid(scale, where), scene_camera(scale, where, persp), BONE, lights=lights(scale, where))
    assert np.isfinite(image).all()
    error = max_error(image, unit_images[persp])
    voxel = scale * float(np.linalg.norm(UNIT_PLACEMENT[:3, 0]))
    tolerance = FLOAT32_ROUNDING + PER_RESOLUTION * resolution_in_voxels(where, voxel)
    assert error <= tolerance, f"{error:.2e} > {tolerance:.2e}"


def test_opacity_saturating_within_a_few_sheets_stays_finite_and_stops_work():
    """An opaque block filling the view: every tile terminates after a handful of sheets, most voxels
    are never splatted (occlusion), and the image is finite and opaque."""
    n = 64
    xf = np.eye(4)
    xf[:3, 3] = -n / 2
    grid = pn.Grid.from_dense(np.ones((n, n, n), np.float32), xf)
    opaque = pn.TransferFunction(density=[0.0, 0.5, 1.0], rgba=[[1, 1, 1, 0], [1, 1, 1, 1], [1, 1, 1, 1]])
    for persp in (False, True):
        cam = scene_camera(1.0, 0.0, persp, width=96, height=96, eye=(3.0, -5.0, 60.0))
        for method in ("pcvr", "regular", "bilinear_spread"):
            stats = {}
            image = pn.render_shaded(grid, cam, opaque, lights=[SUN], method=method, stats=stats)
            assert np.isfinite(image).all()
            # The sampled opacity reaches the cut-off (0.99) within the first sheets; the
            # composite then has nothing to add. Measured 0.9986 at the least.
            assert image[..., 3].min() >= 0.99, method
            assert stats["tiles_terminated"] == stats["tiles"] > 0, (method, stats)
            # Measured: at most 3826 of 262144 voxels splatted (1.5%); 8 sheets of 96 at most.
            assert stats["voxels"] <= 0.03 * n ** 3, (method, stats["voxels"])
            assert stats["sheets"] <= 10, (method, stats["sheets"])


@pytest.mark.parametrize("density", [1e30, 1e-30])
def test_densities_near_float_range_shade_as_unit_densities(unit_images, density):
    """The same scene with densities and the transfer function's domain scaled together."""
    scaled_tf = pn.TransferFunction(density=np.array([0.0, 0.3, 0.6, 1.0]) * density,
                                    rgba=[[0, 0, 0, 0], [0.8, 0.4, 0.3, 0.0], [0.9, 0.8, 0.6, 0.4], [1, 1, 1, 0.9]])
    grid = ct_grid(values=(CT.values.astype(np.float64) * density).astype(np.float32))
    image = pn.render_shaded(grid, scene_camera(1.0, 0.0, True), scaled_tf, lights=lights())
    assert np.isfinite(image).all()
    # Gradients are divided by their largest component before they are squared, so only float32's
    # rounding of the scaled densities remains: measured 1.5e-6 of the peak (40% before).
    assert max_error(image, unit_images[True]) <= 5e-6
    mip = pn.render_mip(grid, scene_camera(1.0, 0.0, True)).astype(np.float64)
    unit_mip = pn.render_mip(ct_grid(), scene_camera(1.0, 0.0, True)).astype(np.float64)
    assert np.isfinite(mip).all()
    assert max_error(mip / density, unit_mip) <= 1e-6  # measured 4e-7: float32 rounding


@pytest.mark.parametrize("method", ["pcvr", "regular"])
@pytest.mark.parametrize("depth", [0.0, 0.25, 0.45])
def test_eye_inside_the_volume(method, depth):
    """The eye inside the CT phantom (depth 0: at its centre; 0.45: near its face), a 70-degree lens
    and a near plane a hundredth of the volume's size ahead: emission and absorption against the ray
    caster. Measured PSNR: 32.1, 33.6 and 34.3 dB for both methods (34.7 at 0.45 for regular); 2 dB
    below that is the bound. (Lit images are left out here: at the centre of a smooth volume the
    gradient vanishes and the shading normal is ill-conditioned for every method.)"""
    grid = pn.Grid.from_dense(phantoms.ct_phantom(48).values, phantoms.ct_phantom(48).index_to_world)
    lo, hi = (np.asarray(b, dtype=np.float64) for b in grid.index_bbox)
    xf = np.asarray(grid.index_to_world)
    centre = xf[:3, :3] @ ((lo + hi) / 2) + xf[:3, 3]
    size = float(np.linalg.norm(xf[:3, :3] @ (hi - lo)))
    eye = centre + np.array([0.1, -0.15, 1.0]) * size * depth
    near = 0.05 if depth == 0.45 else 0.01
    cam = pn.Camera(cameras.look_at(eye, centre - np.array([0.0, 0.0, size]), (0.0, 1.0, 0.0)),
                    cameras.perspective(np.radians(70.0), 1.0, near * size, 3.0 * size), 64, 64)
    unlit = dict(lights=[], ambient=(1.0, 1.0, 1.0))
    reference = pn.render_shaded(grid, cam, BONE, method="raycast", **unlit).astype(np.float64)
    image = pn.render_shaded(grid, cam, BONE, method=method, **unlit).astype(np.float64)
    mse = float(np.mean((image - reference) ** 2))
    measured = {0.0: 32.1, 0.25: 33.6, 0.45: 34.3}[depth]
    assert 10 * np.log10(1.0 / mse) >= measured - 2.0


@pytest.mark.parametrize("persp", [False, True], ids=["ortho", "persp"])
def test_thread_counts_give_the_same_bits(persp):
    """Tiles are rendered whole by one thread each and walk their sheets front to back, so the image
    cannot depend on how many threads there are (shaded and MIP, every splatting method)."""
    grid, cam = ct_grid(), scene_camera(1.0, 0.0, persp, width=80, height=64)
    for method in ("pcvr", "regular", "bilinear_spread"):
        shaded = [pn.render_shaded(grid, cam, BONE, lights=[SUN], method=method, threads=t, tile_size=16) for t in (1, 2, 3)]
        mips = [pn.render_mip(grid, cam, method=method, threads=t, tile_size=16) for t in (1, 2, 3)]
        assert all(np.array_equal(shaded[0], s) for s in shaded[1:]), method
        assert all(np.array_equal(mips[0], m) for m in mips[1:]), method
