"""A colour per voxel (render_shaded(..., albedo_grids=(red, green, blue)), src/shaded/light/albedo_field.h): three
grids on the volume's voxels whose density-weighted colour multiplies the transfer function's at each sample,
as Blender's Color Attribute multiplies the Principled Volume's Color; the ray caster reads the same factor."""

from __future__ import annotations

import numpy as np
import pcvr_native as pn
import pytest

from shaded_scenes import SUN, camera, psnr
from shadow_scenes import pcvr_and_reference

WHITE = pn.TransferFunction(density=[0.0, 0.5, 1.0], rgba=[[1, 1, 1, 0], [1, 1, 1, 0.3], [1, 1, 1, 0.8]])
SCATTER = dict(lights=[SUN], ambient=(0.1, 0.1, 0.1), shading=pn.Shading(model="scatter"))


def blob_values(n: int = 24) -> np.ndarray:
    """A smooth ball of density up to 1, zero (inactive) beyond radius n / 3."""
    i = np.indices((n, n, n), dtype=np.float64) - (n - 1) / 2
    r = np.sqrt((i ** 2).sum(axis=0))
    values = np.clip(1.2 - r / (n / 3), 0.0, 1.0)
    values[r > n / 3] = 0.0
    return values.astype(np.float32)


def colour_grids(colour: np.ndarray, xf=np.eye(4)) -> tuple:
    """(red, green, blue) Grids of a (n, n, n, 3) colour array; zeros inactive."""
    return tuple(pn.Grid.from_dense(np.ascontiguousarray(colour[..., c], dtype=np.float32), xf) for c in range(3))


def coloured_where_dense(density: np.ndarray, rgb) -> np.ndarray:
    """The colour `rgb` on every voxel with density, zero (inactive) elsewhere: Mantaflow's colour grid."""
    return np.where(density[..., None] > 0, np.asarray(rgb, dtype=np.float32), np.float32(0.0))


@pytest.mark.parametrize("method", ["pcvr", "raycast"])
def test_a_colour_where_the_density_is_tints_the_whole_volume(method):
    """Every voxel with density has colour c and the rest none: density-weighted, every sample's factor is c, rim
    and fringe included, so the image is the one whose transfer function is c (to float rounding). Unweighted,
    the rim would blend c with the zeros outside and darken."""
    density = blob_values()
    grid = pn.Grid.from_dense(density, np.eye(4))
    rgb = (0.9, 0.5, 0.2)
    cam = camera(grid, "ortho", 2.0)
    kw = dict(SCATTER, method=method, pixel_step=3 if method == "raycast" else 1)
    image = pn.render_shaded(grid, cam, WHITE, albedo_grids=colour_grids(coloured_where_dense(density, rgb)), **kw)
    tinted = pn.TransferFunction(density=[0.0, 0.5, 1.0], rgba=[[*rgb, 0], [*rgb, 0.3], [*rgb, 0.8]])
    expected = pn.render_shaded(grid, cam, tinted, **kw)
    assert expected[..., 3].max() > 0.5
    np.testing.assert_allclose(image, expected, rtol=0, atol=2e-6)


def halves() -> tuple[pn.Grid, tuple]:
    """The ball red on the side x < n / 2, blue on the other: an edge of colour across the density."""
    density = blob_values()
    n = density.shape[0]
    colour = coloured_where_dense(density, (1.0, 0.2, 0.1))
    colour[n // 2:] = coloured_where_dense(density[n // 2:], (0.1, 0.3, 1.0))
    return pn.Grid.from_dense(density, np.eye(4)), colour_grids(colour)


def test_an_edge_of_colour_renders_as_the_ray_caster_has_it():
    """pcvr against the ray caster (its samples read the same factor at their points) is as near with the colours
    as without them (measured: 53.2 dB with, 52.9 without, at 2 pixels per voxel), and each half shows its own."""
    grid, colours = halves()
    cam = camera(grid, "ortho", 2.0, direction=(0.0, 0.0, -1.0))
    image, reference = pcvr_and_reference(grid, cam, WHITE, **SCATTER, albedo_grids=colours)
    white, white_reference = pcvr_and_reference(grid, cam, WHITE, **SCATTER)
    assert psnr(image, reference) > psnr(white, white_reference) - 1.0 > 45.0
    seen = reference[..., 3] > 0.3
    columns = np.nonzero(seen.any(axis=0))[0]
    left, right = reference[:, columns[:3]][seen[:, columns[:3]]], reference[:, columns[-3:]][seen[:, columns[-3:]]]
    assert np.all(left[:, 0] > 3 * left[:, 2]) and np.all(right[:, 2] > 3 * right[:, 0])


def test_the_factor_is_the_density_weighted_colour_of_the_voxels_around():
    """Two voxels side by side along x, densities 1 and 3, colours red and blue, seen along z through the pair's
    middle by one pixel: trilinear weights 1/2 each there, so the factor is (1 red + 3 blue) / 4."""
    density = np.zeros((4, 3, 3), dtype=np.float32)
    density[1, 1, 1], density[2, 1, 1] = 1.0, 3.0
    colour = np.zeros((4, 3, 3, 3), dtype=np.float32)
    colour[1, 1, 1], colour[2, 1, 1] = (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)
    grid = pn.Grid.from_dense(density, np.eye(4))
    view = np.eye(4)
    view[:3, 3] = [-1.5, -1.0, -10.0]  # the camera above the pair's middle, looking down -z
    half, near, far = 0.01, 0.1, 100.0  # one pixel 0.02 wide (orthographic)
    projection = np.diag([1 / half, 1 / half, -2 / (far - near), 1.0])
    projection[2, 3] = -(far + near) / (far - near)
    cam = pn.Camera(view, projection, 1, 1)
    tf = pn.TransferFunction(density=[0.0, 3.0], rgba=[[1, 1, 1, 0.0], [1, 1, 1, 0.5]])
    kw = dict(lights=[], ambient=(1, 1, 1), shading=pn.Shading(model="scatter"), method="raycast", sheet_spacing=0.05)
    image = pn.render_shaded(grid, cam, tf, albedo_grids=colour_grids(colour), **kw)[0, 0]
    assert image[3] > 0.05
    np.testing.assert_allclose(image[:3] / image[3], [0.25, 0.0, 0.75], atol=1e-3)


def test_a_level_of_detail_takes_its_colours_along():
    grid, colours = halves()
    cam = camera(grid, "ortho", 0.5, direction=(0.0, 0.0, -1.0))
    stats: dict = {}
    image = pn.render_shaded(grid, cam, WHITE, **SCATTER, albedo_grids=colours, level=1, stats=stats)
    assert stats["level"] == 1
    seen = image[..., 3] > 0.3
    columns = np.nonzero(seen.any(axis=0))[0]
    left, right = image[:, columns[0]][seen[:, columns[0]]], image[:, columns[-1]][seen[:, columns[-1]]]
    assert np.all(left[:, 0] > 2 * left[:, 2]) and np.all(right[:, 2] > 2 * right[:, 0])


def test_bad_albedo_grids_are_named():
    grid, colours = halves()
    cam = camera(grid, "ortho", 1.0)
    moved = tuple(g.with_index_to_world(np.diag([2.0, 2.0, 2.0, 1.0])) for g in colours)
    with pytest.raises(ValueError, match="does not lie on the voxels"):
        pn.render_shaded(grid, cam, WHITE, albedo_grids=moved)
    with pytest.raises(ValueError, match="albedo_grids"):
        pn.render_shaded(grid, cam, WHITE, albedo_grids=colours[:2])
    with pytest.raises(ValueError, match="albedo_grids"):
        pn.render_shaded([grid, grid], cam, WHITE, albedo_grids=[colours])
    # None for a grid: no colours there.
    plain = pn.render_shaded([grid, grid], cam, WHITE)
    np.testing.assert_array_equal(pn.render_shaded([grid, grid], cam, WHITE, albedo_grids=[None, None]), plain)
