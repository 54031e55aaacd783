"""MIP mode: the largest reconstructed density along each ray, against a direct computation in numpy, and its
colours through the transfer function."""

import numpy as np
import pytest
from pcvr_native import phantoms

import blender_scenes as bs
import lit_scenes as ls

N, VOXEL, SIZE = 10, 0.1, 28  # voxels per side and their size; image pixels per side
TOP = 10.0  # tf_max of the greyscale test: the Combined pass shows maximum / TOP


@pytest.fixture
def blobs(tmp_path):
    """Two Gaussian blobs (sigma 1.5 and 1 voxels) off the grid's centre, seen from straight above: smooth
    enough for the sheets' slabs to find their peaks, as a CT or a simulation would be."""
    values = phantoms.gaussian_blobs(N, [((4.3, 4.6, 3.8), 1.5, 1.0), ((6.5, 3.0, 6.0), 1.0, 0.7)],
                                     cutoff=0.02).values
    obj = bs.add_volume("Blobs", bs.write_vdb(tmp_path / "blobs.vdb", values, bs.centred(VOXEL, N)))
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=SIZE * VOXEL / 2)  # two pixels per voxel
    return obj, values


def direct_mip(values, step=0.05):
    """For each pixel of the camera above, the largest of sum_i v_i h(|p - i|) (h: the normalised gauss1.4
    kernel of pcvr_native.phantoms) at points p every `step` voxels down its ray."""
    raw, radius, norm = phantoms.kernel_profile("gauss1.4")
    centre = (N - 1) / 2
    pixel = 0.5  # voxels per pixel
    # Pixel centres in index coordinates: row 0 on top (+y), column 0 on the left (-x).
    xs = centre + (np.arange(SIZE) + 0.5 - SIZE / 2) * pixel
    ys = centre - (np.arange(SIZE) + 0.5 - SIZE / 2) * pixel
    zs = np.arange(-radius, N - 1 + radius, step)
    index = np.indices(values.shape).reshape(3, -1).T
    weights = values.reshape(-1)
    image = np.zeros((SIZE, SIZE))
    for row, y in enumerate(ys):
        for column, x in enumerate(xs):
            near = (np.abs(index[:, 0] - x) < radius) & (np.abs(index[:, 1] - y) < radius) & (weights != 0)
            if not near.any():
                continue
            points = np.stack([np.full_like(zs, x), np.full_like(zs, y), zs], axis=1)
            distance = np.linalg.norm(points[:, None, :] - index[near][None, :, :], axis=2)
            image[row, column] = (norm * raw(distance) @ weights[near]).max()
    return image


# Largest errors relative to the peak, measured: regular 1.1%; post-convolved with Catmull-Rom 3.2%, with
# bilinear interpolation 9.3% (it flattens the small blob's peak, two pixels per voxel).
@pytest.mark.parametrize("method, post_filter, tolerance", [('REGULAR', 'BILINEAR', 0.02),
                                                            ('PCVR', 'CATMULL_ROM', 0.05),
                                                            ('PCVR', 'BILINEAR', 0.12)])
def test_mip_matches_the_largest_density_along_each_ray(blobs, method, post_filter, tolerance):
    obj, values = blobs
    scene = ls.shaded_setup(SIZE, SIZE, method=method, mode='MIP')
    scene.pcvr.mip_color = 'GREYSCALE'
    scene.pcvr.sheet_post_filter = post_filter
    settings = obj.data.pcvr
    settings.use_grid_range, settings.tf_min, settings.tf_max = False, 0.0, TOP
    maximum = ls.combined(bs.render(scene))[..., 0] * TOP
    expected = direct_mip(values)
    assert expected.max() > 0.5 and (expected == 0).any()
    # The sheets hold slab means, which a parabola corrects towards the peak (pcvr_native's MIP tests).
    error = np.abs(maximum - expected).max() / expected.max()
    assert error < tolerance
    if method == 'REGULAR':  # the post-filter of the subgrid methods reaches a node further
        assert (maximum[expected == 0] == 0).all()


def test_mip_colours_through_the_transfer_function(blobs):
    obj, _values = blobs
    scene = ls.shaded_setup(SIZE, SIZE, method='REGULAR', mode='MIP')
    settings = obj.data.pcvr
    settings.set_transfer_function(0.0, TOP, [(0.0, (0.0, 0.0, 1.0, 1.0)), (0.1, (1.0, 0.5, 0.0, 0.2))])
    scene.pcvr.mip_color = 'GREYSCALE'
    maximum = ls.combined(bs.render(scene))[..., 0] * TOP
    scene.pcvr.mip_color = 'TRANSFER_FUNCTION'
    colours = ls.combined(bs.render(scene))
    reached = maximum != 0
    # Blue at 0 to orange at density 1 (position 0.1 of 0..10), orange above; opacity plays no part.
    t = np.clip(maximum, 0.0, 1.0)
    expected = np.stack([t, 0.5 * t, 1.0 - t], axis=-1) * reached[..., None]
    np.testing.assert_allclose(colours[..., :3], expected, atol=1e-5)
    np.testing.assert_array_equal(colours[..., 3], reached.astype(np.float32))
