"""Values: densities from denormals to 3e38, negative and mixed signs, empty and single-voxel grids,
one voxel far from the rest, and ten thousand voxels on one pixel.

Splats multiply a power of two into their float stages that brings the largest density near 1, and
the image divides it out: every method then matches its own unit-density image times the density,
up to float32 rounding (measured <= 2.3e-7 of the peak) or, for denormal results, the output's own
quantum (2^-149). A line integral beyond float32's range is refused with the numbers, never NaN."""

import numpy as np
import pytest

import pcvr_native as pn
from pcvr_native import cameras, phantoms

from _io_helpers import HAVE_BPY, run_blender_openvdb, run_python
from stress_helpers import METHODS, max_error, measures_memory
from xray_helpers import frame_ortho, frame_perspective, render_xray_paper

PHANTOM = phantoms.dense_volume(16, seed=4)
FLOAT32_ROUNDING = 5e-7   # twice the largest error measured for normal densities
SMALLEST_DENORMAL = 2.0 ** -149
FRAMES = [frame_ortho, frame_perspective]


@pytest.fixture(scope="module")
def unit():
    grid = PHANTOM.grid()
    out = {}
    for frame in FRAMES:
        cam = frame(PHANTOM, 2.0, (0.3, -0.5, -1.0)).camera()
        out[frame] = cam, {m: render_xray_paper(grid, cam, method=m).astype(np.float64) for m in METHODS}
    return out


@pytest.mark.parametrize("frame", FRAMES)
@pytest.mark.parametrize("density", [1e30, 1e38, 1e-38, 1e-40, 1e-44])
def test_density_from_denormal_to_near_float_max(unit, frame, density):
    cam, references = unit[frame]
    grid = pn.Grid.from_dense(PHANTOM.values.astype(np.float64) * density, PHANTOM.index_to_world)
    for method in METHODS:
        image = render_xray_paper(grid, cam, method=method).astype(np.float64)
        assert np.isfinite(image).all(), method
        reference = references[method] * density
        # A result in the denormal range is quantised to 2^-149 (a few quanta: sums of roundings).
        tolerance = FLOAT32_ROUNDING + 4 * SMALLEST_DENORMAL / np.abs(reference).max()
        assert max_error(image, reference) <= tolerance, f"{method}: {max_error(image, reference):.2e} > {tolerance:.2e}"


@pytest.mark.parametrize("method", METHODS)
def test_line_integral_beyond_float_range_is_refused(method):
    grid = pn.Grid.from_dense(PHANTOM.values * np.float32(2e38), PHANTOM.index_to_world)
    with pytest.raises(ValueError, match=r"exceeds float32's range .* pixels .*density_scale"):
        render_xray_paper(grid, frame_ortho(PHANTOM, 2.0).camera(), method=method)


def test_values_beyond_float_range_are_named_when_the_grid_is_made():
    values = np.ones((4, 4, 4))
    values[1, 2, 3] = 1e39
    with pytest.warns(RuntimeWarning), pytest.raises(pn.GridError, match=r"1e\+39 at \[1, 2, 3\] is beyond float32's range"):
        pn.Grid.from_dense(values, np.eye(4))


@pytest.mark.parametrize("scale", [float("nan"), float("inf")])
def test_non_finite_density_scale_is_refused(scale):
    with pytest.raises(ValueError, match="density_scale must be finite"):
        render_xray_paper(PHANTOM.grid(), frame_ortho(PHANTOM, 2.0).camera(), density_scale=scale)


@pytest.mark.parametrize("frame", FRAMES)
def test_negative_and_mixed_densities_are_linear(unit, frame):
    cam, references = unit[frame]
    mixed = PHANTOM.values.copy()
    mixed[::2] *= -3.0
    flipped = pn.Grid.from_dense(-PHANTOM.values, PHANTOM.index_to_world)
    grid = pn.Grid.from_dense(mixed, PHANTOM.index_to_world)
    for method in METHODS:
        np.testing.assert_array_equal(render_xray_paper(flipped, cam, method=method), -references[method], err_msg=method)
        positive = np.where(mixed > 0, mixed, 0.0)
        parts = [render_xray_paper(pn.Grid.from_dense(p, PHANTOM.index_to_world), cam, method=method).astype(np.float64)
                 for p in (positive, positive - mixed)]
        image = render_xray_paper(grid, cam, method=method)
        assert max_error(image + parts[1], parts[0]) <= FLOAT32_ROUNDING * 4, method


@pytest.mark.parametrize("background", [0.0, -1.0], ids=["no active voxels", "active zeros"])
def test_all_zero_grids_render_black(background):
    grid = pn.Grid.from_dense(np.zeros((9, 9, 9), np.float32), np.eye(4), background=background)
    assert grid.active_voxel_count == (0 if background == 0 else 729)
    for frame in FRAMES:
        cam = frame((np.ones((9, 9, 9)), np.eye(4)), 2.0).camera()
        for method in METHODS:
            stats = {}
            image = render_xray_paper(grid, cam, method=method, stats=stats)
            assert image.shape == (cam.height, cam.width) and not image.any(), method


@pytest.mark.parametrize("frame", FRAMES)
def test_single_voxel_grid(frame):
    values = np.zeros((1, 1, 1), np.float32)
    values[0, 0, 0] = 2.5
    grid = pn.Grid.from_dense(values, np.eye(4))
    cam = frame((np.ones((1, 1, 1)), np.eye(4)), 6.0).camera()
    exact = render_xray_paper(grid, cam, method="exact")
    assert exact.max() > 0
    # regular: the footprint table (2e-3, perspective adds the linearisation of a footprint 3 radii deep: 2e-3 measured).
    assert max_error(render_xray_paper(grid, cam, method="regular", antialias=False), exact) < 5e-3


SPARSE_CORNERS = [(0, 0, 0), (2 ** 31 - 9, -(2 ** 31) + 8, 1_000_000)]


@measures_memory
@pytest.mark.skipif(not HAVE_BPY, reason="writes a sparse grid with Blender's OpenVDB")
def test_one_voxel_far_from_the_rest_stays_small_and_quick(tmp_path):
    """Two voxels 4e9 voxels apart (near both ends of OpenVDB's int32 index range): the index
    bounding box holds 1e28 voxels, the grid two blocks. A render walks two blocks and allocates its
    image and splat grids only (RSS grows by less than 30 MB, measured 0.4 MB after four 255 x 255
    renders of about 1 ms each), dense copies are refused with the size, and exact agrees."""
    path = tmp_path / "far.vdb"
    run_blender_openvdb(f"""
        g = vdb.FloatGrid(); g.name = 'density'
        acc = g.getAccessor()
        for ijk in {SPARSE_CORNERS!r}:
            acc.setValueOn(ijk, 1.0)
        vdb.write({str(path)!r}, [g])
    """)
    proc = run_python(f"""
        import numpy as np, pcvr_native as pn
        from pcvr_native import cameras
        def rss():
            return int(open('/proc/self/statm').read().split()[1]) * 4096
        g = pn.read_vdb({str(path)!r})
        print('BLOCKS', g.block_count, 'VOXELS', g.active_voxel_count)
        try:
            g.to_dense()
        except ValueError as e:
            print('DENSE', e)
        # Both voxels in view; the origin's on the centre of pixel (127, 127), where a ray meets it.
        w2c = cameras.look_at((0, 0, 5e9), (0, 0, 0), (0, 1, 0))
        cam = pn.Camera(w2c, cameras.ortho(-3e9, 3e9, -3e9, 3e9, 1e9, 1e10), 255, 255)
        before = rss()
        for method in ('exact', 'regular', 'pcvr', 'bilinear_spread'):
            stats = {{}}
            image = pn.render_xray(g, cam, method=method, stats=stats, antialias=False, passband="paper")
            print('RENDER', method, stats['blocks'], np.count_nonzero(image), float(image.sum()))
        print('GROWTH', rss() - before)
    """)
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    assert "BLOCKS 2 VOXELS 2" in out and "too many for a dense array" in out, out
    sums = {}
    for line in out.splitlines():
        if line.startswith("RENDER"):
            _, method, blocks, nonzero, total = line.split()
            assert int(nonzero) > 0 and (method == "exact" or blocks == "2"), line
            sums[method] = float(total)
    for method in ("regular", "pcvr"):
        assert sums[method] == pytest.approx(sums["exact"], rel=1e-3), (method, sums)
    growth = int(out.split("GROWTH")[1].split()[0])
    assert growth < 30 * 2 ** 20, f"RSS grew by {growth / 2 ** 20:.0f} MB"


@pytest.mark.parametrize("first_depth", [0.5, 40.0])
def test_ten_thousand_voxels_on_one_pixel_in_perspective(first_depth):
    """A column of 10^4 voxels along the view axis of a 1 x 1 perspective image, starting half a
    voxel from the eye (exact per-ray footprints) or 40 voxels out (linearised): the axis passes
    through every centre, so each voxel adds the same amount and the pixel is the column's sum times
    one voxel's value, to 1e-5 (float32 accumulation would lose 1e-4)."""
    n = 10_000
    column = np.full((1, 1, n), 0.7, dtype=np.float32)
    column[:, :, ::7] = 0.3
    xf = np.eye(4)
    xf[2, 3] = -first_depth - (n - 1)  # voxel k at z = k - n + 1 - first_depth: nearest at -first_depth
    single = np.zeros_like(column)
    single[0, 0, -1] = 1.0
    cam = pn.Camera(np.eye(4), cameras.perspective(1e-3, 1.0, 0.1, 2.0 * n), 1, 1)
    for method in ("exact", "regular", "pcvr"):
        total = render_xray_paper(pn.Grid.from_dense(column, xf), cam, method=method, antialias=False)[0, 0]
        one = render_xray_paper(pn.Grid.from_dense(single, xf), cam, method=method, antialias=False)[0, 0]
        expected = float(np.sum(column, dtype=np.float64)) * float(one)
        assert abs(total / expected - 1.0) < 1e-5, f"{method}: {total} vs {expected}"
