"""pn.read_vdb_vector: a vector grid (a smoke simulation's `color`) read as three float Grids on its voxels, for
render_shaded's albedo_grids; written here by Blender's bundled OpenVDB."""

import numpy as np
import pcvr_native as pn
import pytest

from _io_helpers import HAVE_BPY, run_blender_openvdb

pytestmark = pytest.mark.skipif(not HAVE_BPY, reason="bpy (Blender's bundled openvdb module) is not installed")
MATRIX = [[0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 0.5, 0], [1, 2, 3, 1]]  # OpenVDB's row-vector convention


@pytest.fixture(scope="module")
def smoke(tmp_path_factory):
    """(path, colour array (n, n, n, 3), density array): 'density' and a vec3s 'color' of a few colours, one
    transform; colours zero (inactive) where there is no density, as Mantaflow writes them."""
    d = tmp_path_factory.mktemp("vector")
    rng = np.random.default_rng(5)
    density = np.where(rng.random((10, 9, 8)) < 0.4, rng.uniform(0.1, 1.0, (10, 9, 8)), 0.0).astype(np.float32)
    colour = np.where(density[..., None] > 0, rng.uniform(0.0, 1.0, (10, 9, 8, 3)), 0.0).astype(np.float32)
    np.save(d / "density.npy", density)
    np.save(d / "colour.npy", colour)
    run_blender_openvdb(f"""
        density = vdb.FloatGrid(); density.name = 'density'
        density.copyFromArray(np.load({str(d / 'density.npy')!r}))
        colour = vdb.Vec3SGrid(); colour.name = 'color'
        colour.copyFromArray(np.load({str(d / 'colour.npy')!r}))
        density.transform = colour.transform = vdb.createLinearTransform({MATRIX!r})
        vdb.write({str(d / 'smoke.vdb')!r}, [density, colour])
    """)
    return str(d / "smoke.vdb"), colour, density


def test_the_components_are_the_vector_grids_values_on_the_density_grids_voxels(smoke):
    path, colour, _density = smoke
    red, green, blue = pn.read_vdb_vector(path, "color")
    density = pn.read_vdb(path, "density")
    assert [g.name for g in (red, green, blue)] == ["color.x", "color.y", "color.z"]
    for c, grid in enumerate((red, green, blue)):
        np.testing.assert_array_equal(np.asarray(grid.index_to_world), np.asarray(density.index_to_world))
        (i0, j0, k0), (i1, j1, k1) = grid.index_bbox
        expected = colour[i0:i1 + 1, j0:j1 + 1, k0:k1 + 1, c]
        np.testing.assert_array_equal(grid.to_dense(), expected)


def test_a_scalar_or_missing_grid_is_refused_by_name(smoke):
    path, _colour, _density = smoke
    with pytest.raises(pn.GridError, match="'density'.*not a vector"):
        pn.read_vdb_vector(path, "density")
    with pytest.raises(pn.GridError, match="no grid named 'colour'.*color"):
        pn.read_vdb_vector(path, "colour")
