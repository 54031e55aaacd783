"""Clip planes and crop boxes (render_*(clip_planes=..., clip_box=...)): the reconstructed field is cut exactly.
X-ray integrates the kept part of each ray (kernels a plane crosses are integrated per pixel: src/splat/cut_splat.h),
shaded and MIP samples count for the share of their stretch of ray inside (src/shaded/classify/sample_clip.h)."""

from __future__ import annotations

import numpy as np
import pytest

import pcvr_native as pn
from pcvr_native import phantoms

from conftest import frame_ortho, frame_perspective, image_mass, render, rel_rmse, volume_mass
from shaded_scenes import SUN, bone_tf, ct_volume, psnr

ALPHA = 1.4  # gauss1.4: h(r) = exp(-1.4 r^2), r < 2 index units
RADIUS = 2.0


def kept_fraction(distance: float) -> float:
    """The share of a gauss1.4 kernel's integral on the kept side of a plane `distance` index units from its
    centre (positive: the centre is kept). A slab at height z through the truncated sphere holds
    2 pi * integral_|z|^R h(u) u du = pi (exp(-a z^2) - exp(-a R^2)) / a."""
    z = np.linspace(-RADIUS, RADIUS, 400001)
    slab = np.exp(-ALPHA * z**2) - np.exp(-ALPHA * RADIUS**2)
    return float(np.trapz(np.where(z >= -distance, slab, 0.0), z) / np.trapz(slab, z))


def smooth_volume(n=20, spacing=0.5):
    """Gaussian blobs: a field whose X-ray pcvr reproduces closely, so that what is measured is the cut."""
    c = (n - 1) / 2
    ph = phantoms.gaussian_blobs(n, [((c, c, c), n / 5, 1.0), ((c + n / 6, c - n / 7, c), n / 9, 0.7)],
                                 index_to_world=phantoms.centred_transform((n, n, n), spacing))
    return ph.values, ph.index_to_world, pn.Grid.from_dense(ph.values, ph.index_to_world)


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def plane_through(point, normal):
    n = unit(normal)
    return (*n, -float(n @ np.asarray(point, dtype=np.float64)))


@pytest.mark.parametrize("distance", [-2.5, -1.3, -0.5, 0.0, 0.25, 0.5, 1.7, 2.5])
def test_a_cut_voxel_keeps_its_kernels_mass_on_the_kept_side(distance):
    """One voxel, a plane `distance` index units from its centre at an angle to the view: the image's integral
    is the kernel's integral over the kept half-space, for every method (analytic truth, computed here by
    quadrature of the kernel's slab profile)."""
    n, spacing = 9, 0.5
    values = np.zeros((n, n, n), np.float32)
    values[4, 4, 4] = 1.0
    xf = phantoms.centred_transform(values.shape, spacing)
    grid = pn.Grid.from_dense(values, xf)
    normal = unit((1.0, 2.0, -2.0))
    centre = xf[:3, :3] @ np.full(3, 4.0) + xf[:3, 3]
    plane = plane_through(centre - normal * distance * spacing, normal)
    cam = frame_ortho((values, xf), 3.0, direction=(0.2, -0.3, -1.0))
    expected = kept_fraction(distance) * volume_mass(values, xf)
    for method in ("pcvr", "regular", "exact"):
        stats = {}
        img = render(grid, cam, method, clip_planes=[plane], stats=stats)
        # The table-free cut path and exact integrate the same segments in double: float rounding and the
        # image's edges; a wholly kept voxel goes through the footprint table (2e-3, conftest.REGULAR_TOL)
        # and pcvr's post filter, which conserves mass at whole strides (1e-3 measured 2e-5).
        assert image_mass(img, cam) == pytest.approx(expected, abs=2e-3 * volume_mass(values, xf)), method
        if method == "pcvr":  # a plane seen at 60 degrees from face-on: the cut voxel goes per pixel
            assert stats["voxels_cut"] == (1 if abs(distance) < RADIUS else 0)


def pixel_ray(cam, column, row):
    """Pixel (column, row)'s ray in world space: its points at NDC depth -1 and 1."""
    to_world = np.linalg.inv(cam.projection @ cam.world_to_camera)
    x, y = (column + 0.5) / cam.width * 2 - 1, 1 - (row + 0.5) / cam.height * 2
    ends = [to_world @ np.array([x, y, z, 1.0]) for z in (-1.0, 1.0)]
    return [e[:3] / e[3] for e in ends]


def test_exact_integrates_the_reconstructed_field_over_the_kept_half_space():
    """A plane between voxel centres: `exact` equals the integral of the reconstructed field (sum of the
    voxels' kernels, sampled along each ray and integrated by the trapezoid rule) over the kept part of
    the ray, at pixels where the cut crosses the footprints."""
    values, xf, grid = smooth_volume(10, 0.5)
    kernel_norm = 1.0 / np.trapz(4 * np.pi * np.linspace(0, 2, 20001) ** 2 * np.exp(-ALPHA * np.linspace(0, 2, 20001) ** 2),
                                 np.linspace(0, 2, 20001))
    to_index = np.linalg.inv(xf)
    # Half a voxel beyond the middle voxel's centre along x (world), between voxel centres 4 and 5.
    plane = (1.0, 0.0, 0.0, -float((xf @ [4.5, 0, 0, 1])[0]))
    cam = frame_ortho((values, xf), 2.0, direction=(0.4, -0.3, -1.0))
    img = render(grid, cam, "exact", clip_planes=[plane])
    centres = np.argwhere(values != 0).astype(np.float64)
    weights = values[values != 0].astype(np.float64)
    for column, row in ((cam.width // 2 + dx, cam.height // 2 + dy) for dx in (-3, 0, 2, 5) for dy in (-4, 1)):
        start, end = pixel_ray(cam, column, row)
        # The ray's stretch through the volume's box widened by the kernel, and on the kept side of the plane
        # (integrating up to the cut itself: a jump inside the rule's range would cost O(step)).
        index_start, index_step = to_index[:3, :3] @ start + to_index[:3, 3], to_index[:3, :3] @ (end - start)
        with np.errstate(divide="ignore"):
            bounds = np.sort(np.stack([(-RADIUS - index_start) / index_step, (9 + RADIUS - index_start) / index_step]), axis=0)
        lo, hi = max(bounds[0].max(), 0.0), min(bounds[1].min(), 1.0)
        rate = float(np.dot(plane[:3], end - start))
        cut_at = -(float(np.dot(plane[:3], start)) + plane[3]) / rate
        lo, hi = (max(lo, cut_at), hi) if rate > 0 else (lo, min(hi, cut_at))
        t = np.linspace(lo, hi, 20001)
        field = np.zeros_like(t)
        for chunk in np.array_split(np.arange(t.size), 20):
            index_points = index_start + np.outer(t[chunk], index_step)
            distance2 = ((index_points[:, None, :] - centres[None, :, :]) ** 2).sum(axis=2)
            field[chunk] = (np.where(distance2 < RADIUS**2, np.exp(-ALPHA * distance2), 0.0) * weights).sum(axis=1)
        truth = np.trapz(field, t) * np.linalg.norm(end - start) * kernel_norm
        # The trapezoid rule across the kernels' truncation (a jump of 0.4% of their peak): measured within
        # 5e-7 of exact uncut at these steps.
        assert img[row, column] == pytest.approx(truth, rel=1e-5, abs=1e-6 * img.max())


@pytest.mark.parametrize("projection", ["ortho", "perspective"])
def test_splatting_methods_match_exact_with_the_same_cut(projection):
    """An oblique plane through a smooth volume: pcvr and regular are as near `exact` cut as uncut (the cut
    voxels are integrated exactly, so the cut adds no error of its own), and complementary half-spaces add
    up to the whole volume."""
    values, xf, grid = smooth_volume(24, 0.25)
    frame = frame_ortho if projection == "ortho" else frame_perspective
    cam = frame((values, xf), 3.0, direction=(0.3, -0.2, -1.0))
    plane = plane_through((0.2, -0.1, 0.05), (1.0, 0.4, -0.3))
    opposite = tuple(-x for x in plane)
    exact, exact_other, exact_whole = (render(grid, cam, "exact", clip_planes=p) for p in ([plane], [opposite], None))
    # Analytic segments in double: the halves add up to float rounding.
    assert np.abs(exact + exact_other - exact_whole).max() <= 1e-5 * exact_whole.max()
    regular = render(grid, cam, "regular", clip_planes=[plane])
    # The cut voxels are exact; the others go through the footprint table (and, in perspective, footprints
    # linearised at each voxel: conftest.regular_tolerance). Measured 1e-5 ortho, 1.8e-4 perspective.
    assert rel_rmse(regular, exact) <= (1e-4 if projection == "ortho" else 1e-3)
    # pcvr's post filter smooths what it splats, and the kept voxels end in a staircase along the plane, which
    # it smooths as it would the edge of a cube: the error of a cut image measured 1.8x (ortho) and 2.0x
    # (perspective) the uncut one's, 1.1% and 0.9% of the peak (RMSE): no more than 2.5x here.
    pcvr, pcvr_whole = render(grid, cam, "pcvr", clip_planes=[plane]), render(grid, cam, "pcvr")
    assert rel_rmse(pcvr, exact) <= 2.5 * rel_rmse(pcvr_whole, exact_whole)


def test_an_edge_on_cut_is_sharp():
    """A plane seen edge-on by an orthographic camera: every ray is wholly kept or wholly cut, so the image is
    the uncut one's on the kept side of the plane's line and zero beyond, from the first pixel centre beyond for
    every method (pcvr masks its image with the line: no per-pixel work, and no post-filter reach across it),
    with no voxel integrated per pixel. Near the edge pcvr is as near exact as uncut (measured 1.64% RMSE of
    the kept side against 1.49% uncut; regular 2.0e-5 either way)."""
    values, xf, grid = smooth_volume(16, 0.5)
    cam = frame_ortho((values, xf), 4.0, direction=(0.0, 0.0, -1.0))
    plane = (1.0, 0.0, 0.0, -0.3)  # keeps x >= 0.3: a vertical edge in this top view
    columns = np.array([pixel_ray(cam, c, 0)[0][0] for c in range(cam.width)])
    beyond = columns < 0.3 - 1e-9
    exact, exact_whole = render(grid, cam, "exact", clip_planes=[plane]), render(grid, cam, "exact")
    for method in ("exact", "regular", "pcvr"):
        stats = {}
        img = render(grid, cam, method, clip_planes=[plane], stats=stats)
        assert np.abs(img[:, beyond]).max() == 0.0, method
        assert img[:, ~beyond].max() > 0.5 * img.max()
        if method == "exact":
            continue
        assert stats["voxels_cut"] == 0
        whole = render(grid, cam, method)
        assert rel_rmse(img[:, ~beyond], exact[:, ~beyond]) <= 1.2 * rel_rmse(whole, exact_whole) + 1e-4, method


def test_a_crop_box_is_its_six_planes_and_culls_blocks():
    values, xf, grid = smooth_volume(32, 0.25)
    cam = frame_ortho((values, xf), 2.0, direction=(0.3, -0.4, -1.0)).camera()
    # The box [-1, 0.5] x [-0.3, 2] x [-2, 0.2]: centre and half-sizes, world-to-box = scale^-1 (p - centre).
    lo, hi = np.array([-1.0, -0.3, -2.0]), np.array([0.5, 2.0, 0.2])
    box = np.diag([*(2.0 / (hi - lo)), 1.0])
    box[:3, 3] = -(hi + lo) / (hi - lo)
    planes = [(1, 0, 0, 1.0), (-1, 0, 0, 0.5), (0, 1, 0, 0.3), (0, -1, 0, 2.0), (0, 0, 1, 2.0), (0, 0, -1, 0.2)]
    for method in ("pcvr", "exact"):
        stats = {}
        boxed = pn.render_xray(grid, cam, method, clip_box=box, stats=stats)
        planed = pn.render_xray(grid, cam, method, clip_planes=planes)
        assert np.abs(boxed - planed).max() <= 1e-6 * planed.max()
    assert stats["blocks_clipped"] == 0  # exact plans no blocks
    stats = {}
    pn.render_xray(grid, cam, clip_box=box, stats=stats)
    # The box keeps about an eighth of the 4^3 blocks' volume.
    assert stats["blocks_clipped"] >= 32 and stats["voxels_cut"] > 0


def test_one_region_per_grid_and_streams(tmp_path):
    """Per-grid lists: a grid with None is not cut; a GridStream is cut batch by batch as its grid is. (The paper's
    passband: clearing a field >= 0's ringing below zero is not linear: test_xray_nonnegative.py.)"""
    values, xf, grid = smooth_volume(20, 0.5)
    cam = frame_ortho((values, xf), 2.0, direction=(0.2, 0.1, -1.0)).camera()
    plane = plane_through((0.3, 0, 0), (1.0, 0.2, 0.1))
    cut = pn.render_xray(grid, cam, clip_planes=[plane], passband="paper")
    whole = pn.render_xray(grid, cam, passband="paper")
    both = pn.render_xray([grid, grid], cam, clip_planes=[[plane], None], passband="paper")
    assert np.abs(both - (cut + whole)).max() <= 1e-5 * both.max()
    box = np.eye(4) * 0.5
    box[3, 3] = 1.0
    boxed = pn.render_xray([grid, grid], cam, clip_box=[None, box], passband="paper")
    assert np.abs(boxed - (whole + pn.render_xray(grid, cam, clip_box=box, passband="paper"))).max() <= 1e-5 * boxed.max()
    path = tmp_path / "blobs.vdb"
    grid.write_vdb(str(path))
    stats = {}
    streamed = pn.render_xray(pn.stream_vdb(str(path), batch_bytes=1), cam, clip_planes=[plane], stats=stats,
                              passband="paper")
    assert stats["voxels_cut"] > 0
    assert np.abs(streamed - cut).max() <= 1e-5 * cut.max()


@pytest.mark.parametrize("render_function", ["render_xray", "render_shaded", "render_mip"])
def test_bad_planes_and_boxes_are_refused_by_name(render_function):
    values, xf, grid = smooth_volume(8, 0.5)
    cam = frame_ortho((values, xf), 1.0).camera()
    call = getattr(pn, render_function)
    extra = (bone_tf(),) if render_function == "render_shaded" else ()
    singular = np.eye(4)
    singular[2, 2] = 0.0
    cases = [({"clip_planes": [(0, 0, 0, 1)]}, "normal (a, b, c) is zero"),
             ({"clip_planes": [(1, 0, float("nan"), 1)]}, "finite"),
             ({"clip_box": singular}, "empty box"),
             ({"clip_box": np.full((4, 4), np.nan)}, "finite"),
             ({"clip_planes": [[(1, 0, 0, 0)], None]}, "per grid"),
             ({"clip_box": [np.eye(4), np.eye(4)]}, "per grid")]
    for kwargs, words in cases:
        with pytest.raises(ValueError, match=words.replace("(", r"\(").replace(")", r"\)")):
            call(grid, cam, *extra, **kwargs)
    with pytest.raises(TypeError, match="clip_planes"):
        call(grid, cam, *extra, clip_planes=[(1, 0, 0)])


@pytest.mark.parametrize("projection", ["ortho", "perspective"])
def test_shaded_cut_matches_the_ray_caster(projection):
    """The CT phantom cut open: the sheets drop what lies beyond the plane as the ray caster does, and both
    light the cut face by the plane's normal; PSNR against the ray caster is as high as uncut. The half the
    plane removes is transparent, and whole blocks beyond it are skipped."""
    grid = ct_volume(40)
    frame = frame_ortho if projection == "ortho" else frame_perspective
    cam = frame(grid, 3.0, direction=(0.5, -0.4, -0.8)).camera()
    plane = (0.0, -1.0, 0.0, 0.05)  # keeps y <= 0.05
    tf = bone_tf()
    stats = {}
    cut = pn.render_shaded(grid, cam, tf, [SUN], clip_planes=[plane], stats=stats)
    reference = pn.render_shaded(grid, cam, tf, [SUN], method="raycast", clip_planes=[plane])
    whole = pn.render_shaded(grid, cam, tf, [SUN])
    whole_reference = pn.render_shaded(grid, cam, tf, [SUN], method="raycast")
    # Measured (40^3): 30.6 / 31.9 dB cut, 29.7 / 31.1 uncut, ortho / perspective.
    assert psnr(cut, reference) >= psnr(whole, whole_reference) - 0.5
    assert stats["blocks_clipped"] > 0
    assert cut[..., 3].sum() < 0.8 * whole[..., 3].sum()


def test_mip_counts_only_samples_inside():
    values, xf, grid = smooth_volume(20, 0.5)
    cam = frame_ortho((values, xf), 2.0, direction=(0.0, 0.0, -1.0))
    plane = (-1.0, 0.0, 0.0, -1.0)  # keeps x <= -1: the blobs' peaks are removed
    cut = pn.render_mip(grid, cam.camera(), clip_planes=[plane])
    reference = pn.render_mip(grid, cam.camera(), method="raycast", clip_planes=[plane])
    whole = pn.render_mip(grid, cam.camera())
    columns = np.array([pixel_ray(cam, c, 0)[0][0] for c in range(cam.width)])
    assert np.abs(cut[:, columns > -1.0 + 0.5]).max() == 0.0  # the background: nothing sampled beyond
    kept = columns < -1.0 - 0.5
    assert np.abs(cut[:, kept] - whole[:, kept]).max() <= 1e-6  # rays wholly inside are not changed
    # Sheet samples against point samples, as uncut (measured 1.2e-3 of the peak at the edge).
    assert np.abs(cut - reference).max() <= 0.02 * whole.max()


@pytest.mark.parametrize("projection", ["ortho", "perspective"])
def test_a_cut_through_homogeneous_matter_is_lit_as_a_flat_face(projection):
    """Inside a homogeneous block the only gradient is the kernels' ripple (their sum over the lattice is one
    to within 0.5%), whose directions follow the lattice: lit by it, the translucent block's own top face shows
    a pattern (measured 5.6% / 6.6% colour deviation here with pcvr, 12% with the ray caster). A cut face, and
    what lies behind it with no gradient stronger than that ripple, is lit by the plane's normal: flat (measured
    7e-5 / 5e-3), and as bright as the ray caster's (within 1e-4)."""
    n = 32
    values = np.zeros((n, n, n), np.float32)
    values[4:-4, 4:-4, 4:-4] = 1.0
    xf = phantoms.centred_transform(values.shape, 0.1)
    grid = pn.Grid.from_dense(values, xf)
    tf = pn.TransferFunction(density=[0.0, 0.5, 1.0], rgba=[[1, 1, 1, 0], [1, 1, 1, 0.3], [1, 1, 1, 0.3]])
    sun = pn.Light.sun(direction=(0.3, -0.5, -0.8))
    frame = frame_ortho if projection == "ortho" else frame_perspective
    cam = frame((values, xf), 3.0, direction=(0.2, 0.3, -1.0)).camera()
    cut = (0.0, 0.0, -1.0, 0.0)  # keeps z <= 0: the face at z = 0 faces the camera

    def face_colour(image):
        h, w = image.shape[:2]
        patch = image[h // 2 - 8:h // 2 + 8, w // 2 - 8:w // 2 + 8]
        return patch[..., :3] / patch[..., 3:4]  # unpremultiplied: the lighting alone

    face = face_colour(pn.render_shaded(grid, cam, tf, [sun], clip_planes=[cut]))
    reference = face_colour(pn.render_shaded(grid, cam, tf, [sun], method="raycast", clip_planes=[cut]))
    assert face.std() <= 0.02 * face.mean()
    assert face.mean() == pytest.approx(reference.mean(), rel=1e-3)


@pytest.mark.parametrize("kernel", ["linear", "box"])
def test_cut_kernels_other_than_gaussians(kernel):
    """Kernels that do not separate along a line take the double path (CutSplatter::add_rows, with
    Kernel::segment_integral): one voxel cut at an angle, through its centre and off it, is the same image with
    pcvr (integrated per pixel), regular (at the pixels as nodes) and exact. Measured within 1e-6 of the peak:
    float rounding."""
    n, spacing = 9, 0.5
    values = np.zeros((n, n, n), np.float32)
    values[4, 4, 4] = 1.0
    xf = phantoms.centred_transform(values.shape, spacing)
    grid = pn.Grid.from_dense(values, xf)
    radius = pn.kernel_info(kernel)["radius"]
    normal = unit((1.0, 2.0, -2.0))
    centre = xf[:3, :3] @ np.full(3, 4.0) + xf[:3, 3]
    cam = frame_ortho((values, xf), 3.0, direction=(0.2, -0.3, -1.0))
    for offset in (-0.5, 0.0, 0.4):
        plane = plane_through(centre - normal * offset * radius * spacing, normal)
        exact = render(grid, cam, "exact", kernel, clip_planes=[plane])
        for method in ("pcvr", "regular"):
            stats = {}
            img = render(grid, cam, method, kernel, clip_planes=[plane], stats=stats)
            assert np.abs(img - exact).max() <= 1e-6 * exact.max(), (method, offset)
            assert stats["voxels_cut"] == (1 if method == "pcvr" else 0)
