"""What fuzzing, the sanitizers and the property tests found (make fuzz, make sanitize, make stress;
docs/reliability.md), each kept as a test. The fuzzer inputs that found them are in
tests/fuzz_regressions/<target>/, which make fuzz replays before it fuzzes."""

from pathlib import Path

import numpy as np
import pytest

import pcvr_native as pn
from pcvr_native import cameras

from _io_helpers import run_python
from stress_helpers import max_error, measures_memory
from xray_helpers import render_xray_paper  # the paper's passband: these compare with exact

REGRESSIONS = Path(__file__).resolve().parents[1] / "fuzz_regressions"


def framed_at_zero_size(grid):
    """fuzz_read_vdb's view of a grid (native/fuzz/fuzz_scene.h, render_framed) whose active box
    has no size: 16 x 16 pixels across 3e-30 units, 1e29 pixels per voxel."""
    (i, j, k), _ = grid.index_bbox
    x, y, z = (grid.index_to_world @ [i, j, k, 1.0])[:3]
    half = 1e-30 * 1.5
    view = np.eye(4)
    view[:3, 3] = -x, -y, -(z + half)
    projection = np.diag([1.0 / half, 1.0 / half, -1.0 / (2.0 * half), 1.0])
    projection[2, 3] = -1.0
    return pn.Camera(view, projection, 16, 16)


def test_exact_footprint_spans_never_overlap():
    """fuzz_render (tests/fuzz_regressions/render/near_eye_spans_overlap): the eye inside a volume
    of 3e8-unit voxels in a 175-degree view. A voxel whose cone of rays reaches past the horizon
    covers a row outside two roots; each span was widened by a node for safety, and where the roots
    lay within two nodes the spans met and those nodes were added twice (16% of the peak)."""
    values = np.array([-1.15625004e26, 0, 0, 0, -5.62500026e25] + [-3.12500008e24] * 20, np.float32).reshape(5, 1, 5)
    index_to_world = np.array([
        [89857048.787927911, 276552267.61449307, 133793123.29077759, -453918766.47681725],
        [-133049720.59810719, -89499708.446124583, 276552267.61449307, -301666131.81618357],
        [-276793602.57095122, 133793123.29077759, -89499708.446124583, 822564819.75156343], [0, 0, 0, 1]])
    world_to_camera = np.array([
        [-0.0064647503831789877, -0.83403192299883544, -0.55167831063161055, 72346050.465472534],
        [0.99740100441770663, 0.03421186209632144, -0.063409659188899792, 13596595.714867121],
        [0.071759622274879115, -0.55065442875797066, 0.83164310656687335, -130154396.62438598], [0, 0, 0, 1]])
    projection = np.array([[0.039251659782720362, 0, 0, 0], [0, 0.028212130468830261, 0, 0],
                           [0, 0, -1.0000000004079967, -33888290.471791863], [0, 0, -1, 0]])
    grid = pn.Grid.from_dense(values, index_to_world)
    cam = pn.Camera(world_to_camera, projection, 23, 32)
    exact = render_xray_paper(grid, cam, method="exact", splat_kernel="gauss2.0")
    for tolerance in (0.04, 0.0):
        regular = render_xray_paper(grid, cam, method="regular", splat_kernel="gauss2.0", footprint_tolerance=tolerance)
        assert max_error(regular, exact) < 2e-3  # measured 5.2e-4: the footprint table


def test_footprint_wider_than_an_int_of_pixels():
    """fuzz_read_vdb (tests/fuzz_regressions/read_vdb/empty_grid_framed_at_zero_size.vdb): a grid
    framed at zero size put 1e30 pixels on a voxel, and the phase window's half width, converted to
    int unclamped, overflowed (undefined behaviour, caught by the sanitizer build). At 2.5e9 pixels
    per voxel every method still agrees with exact."""
    values = np.ones((1, 1, 1), np.float32)
    grid = pn.Grid.from_dense(values, np.eye(4))
    cam = pn.Camera(cameras.look_at((0, 0, 10), (0, 0, 0), (0, 1, 0)), cameras.ortho(-1e-9, 1e-9, -1e-9, 1e-9, 1, 100), 4, 4)
    exact = render_xray_paper(grid, cam, method="exact")
    for method in ("regular", "pcvr"):
        assert max_error(render_xray_paper(grid, cam, method=method), exact) < 2e-3, method
    empty = pn.read_vdb(REGRESSIONS / "read_vdb" / "empty_grid_framed_at_zero_size.vdb")
    for method in ("exact", "regular", "pcvr", "bilinear_spread"):
        assert not render_xray_paper(empty, framed_at_zero_size(empty), method=method).any(), method


def test_delayed_load_table_whose_blosc_header_disagrees():
    """fuzz_read_vdb, after 110,000 runs: grid metadata of type DelayedLoadMetadata holds a per-leaf
    table as a blosc chunk, which OpenVDB reads into a buffer of the stored size and hands to blosc,
    which trusts the chunk's own header. A header saying 58 bytes for a chunk stored as 56 read past
    the buffer (AddressSanitizer: heap-buffer-overflow in LZ4_decompress_safe, via list_grids). The
    reader now checks both sizes against the header first. Kept input: a pcvr_native file with that
    one size field changed."""
    path = REGRESSIONS / "read_vdb" / "delayed_load_blosc_header.vdb"
    for call in (pn.read_vdb, pn.list_grids):
        with pytest.raises(pn.VDBReadError, match=r"delayed_load_blosc_header\.vdb.*corrupt grid metadata \(delayed-load table\)"):
            call(path)


def test_corrupt_topology_chunk_is_a_clear_error():
    """fuzz_read_vdb (tests/fuzz_regressions/read_vdb/topology_blosc_chunk_corrupt.vdb): a blosc
    chunk in a tree's topology that the reader's checks pass but blosc cannot decompress. OpenVDB
    throws, and leaks the node it was reading into (LeakSanitizer; OpenVDB's, suppressed in
    native/fuzz/leak_suppressions.txt): the read fails with the file and the cause; the listing,
    which reads no topology, still names the grid."""
    path = REGRESSIONS / "read_vdb" / "topology_blosc_chunk_corrupt.vdb"
    with pytest.raises(pn.VDBReadError, match=r"topology_blosc_chunk_corrupt\.vdb.*Expected to decompress 4 bytes"):
        pn.read_vdb(path)
    assert [g["name"] for g in pn.list_grids(path)] == ["density"]


def test_bilinear_spreading_a_voxel_wider_than_the_int_range():
    """fuzz_read_vdb (tests/fuzz_regressions/read_vdb/one_voxel_framed_at_zero_size.vdb, one voxel
    two index units from its block's origin): at 1e29 pixels per voxel bilinear spreading's stride is
    clamped to 65536, its nodes lay 1e25 apart within the block, and the batched splat converted the
    block origin's node to int out of range (undefined). Such views now splat voxel by voxel."""
    grid = pn.read_vdb(REGRESSIONS / "read_vdb" / "one_voxel_framed_at_zero_size.vdb")
    cam = framed_at_zero_size(grid)
    for method in ("exact", "regular", "pcvr", "bilinear_spread"):
        assert np.isfinite(render_xray_paper(grid, cam, method=method)).all(), method


@measures_memory
def test_stride_from_a_corner_at_the_eye_stays_bounded():
    """test_properties (test_never_nan_and_the_same_for_any_thread_count): a block's corner 1e-18
    in front of the eye made its magnification 1.4e18 pixels per voxel, bilinear spreading's stride
    the int conversion of half that, and its post filter's tables (per pixel of stride) took 24 GB
    before the out-of-memory killer took the process. Strides are clamped to 65536 now; under a
    2 GiB address-space limit the render completes."""
    proc = run_python("""
        import resource, numpy as np, pcvr_native as pn
        resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))
        values = np.array([[[1.0, 0.6125948], [0.1778497, 0.1314025]],
                           [[1.6452135, 1.8342355], [1.252608, 1.4860435]]], np.float32)
        index_to_world = np.array([[1.0, 0, 0, -0.5], [0, 1.0, 0, -0.5], [0, 0, 1.5625, -0.78125], [0, 0, 0, 1.0]])
        world_to_camera = np.array([[-1.0, 0, 0, -0.5],
                                    [0, 0.99999999999998745, -1.5894571941954538e-07, 0.49999987582365041],
                                    [0, -1.5894571941954538e-07, -0.99999999999998745, -0.78125007947284997],
                                    [0, 0, 0, 1.0]])
        projection = np.array([[1.830487721712452, 0, 0, 0], [0, 1.830487721712452, 0, 0],
                               [0, 0, -1.0002000200020003, -2.3210265194583353], [0, 0, -1.0, 0]])
        grid = pn.Grid.from_dense(values, index_to_world)
        for method in ('exact', 'regular', 'pcvr', 'bilinear_spread'):
            stats = {}
            image = pn.render_xray(grid, pn.Camera(world_to_camera, projection, 40, 40), method=method, stats=stats)
            assert np.isfinite(image).all()
            print(method, max(stats.get('strides') or [0]))
    """)
    assert proc.returncode == 0, proc.stderr
    assert all(float(line.split()[1]) <= 65536 for line in proc.stdout.splitlines()), proc.stdout


# ---- Shaded and MIP (fuzz_shaded, make sanitize) ----------------------------------------------

def shaded_block(side=8):
    """A dense block of random densities in [0, 1], seen orthographically from +z, 32 x 32 pixels
    (one tile): every voxel is splatted once."""
    values = np.random.default_rng(5).random((side, side, side)).astype(np.float32) + 0.01
    grid = pn.Grid.from_dense(values, np.eye(4))
    c = (side - 1) / 2
    cam = pn.Camera(cameras.look_at((c, c, 40.0), (c, c, c), (0, 1, 0)), cameras.ortho(-6, 6, -6, 6, 1, 100), 32, 32)
    return grid, cam


def ramp(opacity=0.3, colour=1.0, unit_distance=None):
    return pn.TransferFunction(density=[0.0, 1.0], rgba=[[colour] * 3 + [0.0], [colour] * 3 + [opacity]], unit_distance=unit_distance)


def test_orthographic_sheets_splat_no_padding_lane():
    """make sanitize, in test_shaded_accuracy: the voxels of a block are splatted in depth order in
    batches of eight, and the batch after a block's last voxel holds padding at infinite depth, whose
    first sheet was converted to int64 (undefined; UBSan: "inf is outside the range of long"), in
    every orthographic shaded render. The fix leaves those lanes alone: each of the 512 voxels is
    still splatted exactly once."""
    grid, cam = shaded_block()
    for method in ("regular", "pcvr", "bilinear_spread"):
        stats = {}
        image = pn.render_shaded(grid, cam, ramp(), [pn.Light.sun((0, 0, -1))], method=method, opacity_cutoff=1.0,
                                 threads=1, stats=stats)
        assert np.isfinite(image).all() and image[..., 3].max() > 0.5, method
        assert stats["voxels"] == 512, (method, stats["voxels"])


def test_sheet_spacing_beyond_what_sheets_can_be_is_refused():
    """fuzz_shaded (tests/fuzz_regressions/shaded/sheet_spacing_1e308): sheets 1.4e308 voxels apart
    made the sheet spacing infinite and the sheet count NaN, converted to int64 (undefined). Sheet
    spacings outside 1e-6 to 1e6 voxels are refused (and sheet indices saturate at 2^60)."""
    grid, cam = shaded_block()
    for spacing in (1.39e308, 2e6, 1e-300, 5e-7):
        with pytest.raises(ValueError, match="sheet_spacing must be a number of voxels from 1e-6 to 1e6"):
            pn.render_mip(grid, cam, sheet_spacing=spacing)
        with pytest.raises(ValueError, match="sheet_spacing must be a number of voxels from 1e-6 to 1e6"):
            pn.render_shaded(grid, cam, ramp(), method="raycast", sheet_spacing=spacing)


def test_large_strides_are_splatted_at_most_at_the_tile_and_image_size():
    """fuzz_shaded (tests/fuzz_regressions/shaded/fixed_stride_22969, stride_on_a_one_pixel_high_image):
    a sheet's gradient reads a node beyond its tile, so each tile's sheets are a stride wider on every
    side. A fixed stride of 22969 on a 33 x 19 image allocated 8.5 GB for one tile (and first hung
    for minutes in PostFilter::overshoot, which went over every pair of the stride's phases: now per
    phase, native/tests), and a stride of 256 made a one-pixel-high image post-convolve 500 times its
    pixels per sheet. Strides are capped at 256, the tile size and the image's smaller side; a capped
    stride renders the same bits as asking for it."""
    grid, cam = shaded_block()
    tf, lights = ramp(), [pn.Light.sun((0, 0, -1))]
    for stride, tile, expected in ((22969, 0, 32), (40, 12, 12), (300, 64, 32)):
        stats = {}
        image = pn.render_shaded(grid, cam, tf, lights, stride=stride, tile_size=tile, threads=1, stats=stats)
        assert stats["strides"] == [expected], (stride, tile, stats["strides"])
        assert np.array_equal(image, pn.render_shaded(grid, cam, tf, lights, stride=expected, tile_size=tile, threads=1))
    thin = pn.Camera(cameras.look_at((3.5, 3.5, 40.0), (3.5, 3.5, 3.5), (0, 1, 0)), cameras.ortho(-6, 6, -0.01, 0.01, 1, 100), 600, 1)
    stats = {}
    assert np.isfinite(pn.render_mip(grid, thin, stats=stats)).all()
    assert stats["strides"] == [1]


def test_densities_beyond_float_range_are_refused():
    """fuzz_shaded (tests/fuzz_regressions/shaded/density_scale_1e307): a density_scale of 1.2e307
    became infinity in the float sheets and MIP returned NaN. Densities times density_scale, and their
    integral over a slab, must stay below 1e36 (the sheets hold them in float32, range 3.4e38)."""
    grid, cam = shaded_block()
    message = r"grid 'density': densities times density_scale reach .*beyond 1e\+36.*scale the densities down with density_scale"
    with pytest.raises(ValueError, match=message):
        pn.render_mip(grid, cam, density_scale=1.2e307)
    with pytest.raises(ValueError, match=message):
        pn.render_shaded(grid, cam, ramp(), density_scale=1e37)
    assert np.isfinite(pn.render_mip(grid, cam, density_scale=1e35)).all()


def test_lighting_and_extinction_beyond_float_range_stay_finite():
    """fuzz_shaded: transfer-function colours, light energies and material coefficients are checked
    finite in double but held in float, and a point light at a sample divides its energy by a
    squared distance of 1e-30; an opacity per 1e-300 units is an infinite extinction. Where an
    infinity met a zero (colour times extinction over their sum, energy times an unlit normal) pixels
    were NaN. Lighting is now bounded at 1e30 per stage and colours mix by extinction shares: the
    image is finite, its alpha within [0, 1] and its colours >= 0."""
    grid, cam = shaded_block()
    centre = [3.0, 3.0, 3.0]  # a voxel's centre: the ray through pixel (16, 16)'s samples cross it
    lights = [pn.Light.point(centre, strength=1e300), pn.Light.point((3.5, 3.5, 40.0), strength=1e300), pn.Light.sun((0, 0, -1), strength=1e300)]
    bright = ramp(opacity=1.0, colour=1e300, unit_distance=1e-300)
    for shading in (pn.Shading(), pn.Shading(ambient=1e300, diffuse=1e300, specular=1e300, shininess=1e300), pn.Shading(lit=False)):
        for method in ("pcvr", "regular", "raycast"):
            image = pn.render_shaded(grid, cam, bright, lights, ambient=(1e300,) * 3, shading=shading, method=method, threads=1)
            assert np.isfinite(image).all(), method
            assert (image[..., :3] >= 0).all() and (image[..., 3] >= 0).all() and (image[..., 3] <= 1).all(), method
            assert image[..., 3].max() == 1.0
