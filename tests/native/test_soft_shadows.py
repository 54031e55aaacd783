"""Soft shadows of a sun with a disc (Light.sun(angle=...), src/shaded/light/penumbra.h) against the ray caster, which
averages shadow rays to 32 points over the disc: a caster covering half of the light's way throws a shadow edge
across a receiver 18 voxels behind it, seen from above."""

import numpy as np
import pcvr_native as pn
import pytest

from shadow_scenes import REFERENCE_SPACING, REFERENCE_STEP, half_caster_and_receiver
from shaded_scenes import camera

TF = pn.TransferFunction(density=[0.0, 0.5, 1.0], rgba=[[1, 1, 1, 0], [1, 1, 1, 0.3], [1, 1, 1, 0.9]])
# Single scattering, no ambient light: a sample's brightness is its transmittance.
KW = dict(shadows=True, opacity_cutoff=1.0, shading=pn.Shading(model="scatter", scattering_octaves=1), ambient=(0, 0, 0))
ALONG_X = (1.0, 0.0, 0.0)


@pytest.fixture(scope="module")
def scene():
    grid = half_caster_and_receiver()
    cam = camera(grid, "ortho", 3.0, direction=(0.0, 0.0, -1.0))
    receiver = np.zeros((40, 32, 24), dtype=np.float32)
    receiver[26:32, 4:28, 4:20] = 0.5
    alone = pn.render_shaded(pn.Grid.from_dense(receiver, np.eye(4)), cam, TF, lights=[], opacity_cutoff=1.0)
    return grid, cam, alone[::REFERENCE_STEP, ::REFERENCE_STEP, 3] > 0.5


def render(grid, cam, angle, **kw):
    return pn.render_shaded(grid, cam, TF, lights=[pn.Light.sun(ALONG_X, angle=angle)], **KW, **kw)


# The receiver's relative RMS error against the soft reference, soft over hard (measured 0.43 and 0.26; at an
# angle of 0.1 the penumbra is about a voxel wide, below the lattice's texel, and soft equals hard: 1.00).
@pytest.mark.parametrize("angle, most", [(0.25, 0.55), (0.5, 0.35)])
def test_the_penumbra_follows_the_ray_casters_disc_of_rays(scene, angle, most):
    grid, cam, receiver = scene
    reference = render(grid, cam, angle, method="raycast", sheet_spacing=REFERENCE_SPACING, pixel_step=REFERENCE_STEP)
    soft = render(grid, cam, angle)[::REFERENCE_STEP, ::REFERENCE_STEP]
    hard = render(grid, cam, 0.0)[::REFERENCE_STEP, ::REFERENCE_STEP]

    def error(image):
        return np.sqrt(np.mean((image - reference)[receiver, :3] ** 2)) / reference[receiver, :3].max()
    assert error(soft) <= most * error(hard), (error(soft), error(hard))


def test_a_wider_disc_widens_the_penumbra(scene):
    """Across the shadow's edge, along the receiver's middle: pixels between 10% and 90% of the lit side's level."""
    grid, cam, receiver = scene
    middle = int(np.argmax(receiver.sum(axis=0)))  # the image column crossing most of the receiver
    widths = []
    for angle in (0.0, 0.25, 0.5):
        profile = render(grid, cam, angle)[::REFERENCE_STEP, ::REFERENCE_STEP, 0][receiver[:, middle], middle]
        lit = profile.max()
        widths.append(int(np.count_nonzero((profile > 0.1 * lit) & (profile < 0.9 * lit))))
    assert widths[0] < widths[1] < widths[2], widths  # measured 2, 5, 8 of every third pixel (3 pixels per voxel)


def test_no_angle_is_the_hard_shadow(scene):
    grid, cam, _receiver = scene
    default = pn.render_shaded(grid, cam, TF, lights=[pn.Light.sun(ALONG_X)], **KW)
    assert np.array_equal(render(grid, cam, 0.0), default)
    assert pn.Light.sun(ALONG_X).angle == 0.0 and pn.Light.sun(ALONG_X, angle=0.3).angle == 0.3


@pytest.mark.parametrize("angle", [-0.1, 3.2, float("nan"), float("inf")])
def test_bad_angles_are_named(angle):
    with pytest.raises(ValueError, match="angle"):
        pn.Light.sun(ALONG_X, angle=angle)
