"""Rendered passes against pcvr_native's "exact" method, for the camera settings Blender offers."""

import numpy as np
import pcvr_native as pn
import pytest
from mathutils import Vector

import blender_scenes as bs
from pcvr_addon.render import statistics


def look_at(camera, target=(0, 0, 0)):
    direction = Vector(target) - camera.location
    camera.rotation_euler = direction.to_track_quat('-Z', 'Y').to_euler()


@pytest.fixture
def blob_object(tmp_path, rng):
    """A lumpy volume, rotated and scaled."""
    filepath = bs.write_vdb(tmp_path / "blob.vdb", bs.blob(rng))
    return bs.add_volume("Blob", filepath, location=(0.05, -0.1, 0.0), rotation=(0.4, 0.2, 0.9),
                         scale=(1.2, 0.8, 1.0))


CAMERAS = {
    "orthographic": dict(location=(0.1, -0.05, 5.0), rotation=(0.0, 0.0, 0.3), ortho_scale=2.4),
    "orthographic_tilted": dict(location=(3.0, -3.0, 2.0), ortho_scale=2.6),
    "perspective": dict(location=(0.4, -3.5, 1.5), lens=40.0),
    "perspective_shifted": dict(location=(-1.0, -3.0, 2.0), lens=50.0, shift=(0.08, -0.05)),
}


@pytest.mark.parametrize("name", CAMERAS)
def test_xray_pass_matches_exact(blob_object, name):
    scene = bs.setup(64, 48)
    camera = bs.add_camera(**CAMERAS[name])
    if "rotation" not in CAMERAS[name]:
        look_at(camera)
    bs.assert_matches(bs.xray(bs.render(scene)), bs.exact(bs.world_grid(blob_object)))


@pytest.mark.parametrize("method", ['REGULAR', 'PCVR'])
def test_xray_pass_takes_the_passband(blob_object, method):
    """The scene's passband reaches render_xray: the default (compensated) renders as pcvr_native does with the
    same camera, and differs from the paper's passband."""
    scene = bs.setup(64, 48, method=method, passband='COMPENSATED')
    bs.add_camera(**CAMERAS["orthographic"])
    image = bs.xray(bs.render(scene))
    native = pn.render_xray(bs.world_grid(blob_object), bs.reference_camera(), method=method.lower(), passband="compensated")
    bs.assert_matches(image, native)
    assert np.abs(image - bs.exact(bs.world_grid(blob_object))).max() > 5 * bs.TOLERANCE * image.max()


def test_pixel_aspect_and_resolution_percentage(blob_object):
    scene = bs.setup(128, 64)
    scene.render.resolution_percentage = 50
    scene.render.pixel_aspect_x = 1.5
    look_at(bs.add_camera(location=(0.5, -3.0, 1.0), lens=35.0))
    image = bs.xray(bs.render(scene))
    assert image.shape == (32, 64)
    bs.assert_matches(image, bs.exact(bs.world_grid(blob_object)))


@pytest.mark.parametrize("crop", [True, False], ids=["crop", "no_crop"])
@pytest.mark.parametrize("border", [(24, 64, 6, 33), (40, 41, 28, 29)], ids=["40x27", "one_pixel"])
def test_render_border(blob_object, crop, border):
    scene = bs.setup(80, 60)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=2.0)
    full = bs.exact(bs.world_grid(blob_object))

    # The border in pixels from the bottom left, set half a pixel inside what Blender truncates it
    # to; rows of images run top down.
    x0, x1, y0, y1 = border
    render = scene.render
    render.use_border, render.use_crop_to_border = True, crop
    render.border_min_x, render.border_max_x = (x0 + 0.5) / 80, (x1 + 0.5) / 80
    render.border_min_y, render.border_max_y = (y0 + 0.5) / 60, (y1 + 0.5) / 60
    image = bs.xray(bs.render(scene))

    rows, columns = slice(60 - y1, 60 - y0), slice(x0, x1)
    if crop:
        bs.assert_matches(image, full[rows, columns])
    else:
        outside = np.ones(full.shape, dtype=bool)
        outside[rows, columns] = False
        assert image.shape == full.shape
        assert not image[outside].any()
        bs.assert_matches(image[rows, columns], full[rows, columns])


def test_overlapping_volumes_add(tmp_path, rng):
    scene = bs.setup(64, 64)
    bs.add_camera(location=(0.0, 0.0, 5.0), rotation=(0.2, -0.1, 0.0), ortho_scale=2.5)
    a = bs.add_volume("A", bs.write_vdb(tmp_path / "a.vdb", bs.blob(rng)), location=(-0.2, 0.0, 0.0))
    b = bs.add_volume("B", bs.write_vdb(tmp_path / "b.vdb", bs.blob(rng, density=2.0)),
                      location=(0.25, 0.1, -0.3), rotation=(0.0, 0.5, 0.0))
    grids = [bs.world_grid(a), bs.world_grid(b)]
    image = bs.xray(bs.render(scene))
    bs.assert_matches(image, bs.exact(grids[0]) + bs.exact(grids[1]))


def test_density_scale(blob_object):
    scene = bs.setup(48, 48)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=2.5)
    blob_object.data.pcvr.density_scale = 2.5
    bs.assert_matches(bs.xray(bs.render(scene)), 2.5 * bs.exact(bs.world_grid(blob_object)))


@pytest.mark.parametrize("transparent", [False, True], ids=["opaque", "transparent"])
def test_combined_pass(blob_object, transparent):
    scene = bs.setup(48, 48)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=3.0)
    scene.pcvr.xray_gain = 0.7
    scene.render.film_transparent = transparent
    passes = bs.render(scene)
    integral, combined = bs.xray(passes), passes["ViewLayer.Combined"]

    expected = 1 - np.exp(-0.7 * integral)
    for channel in range(3):
        np.testing.assert_allclose(combined[:, :, channel], expected, atol=1e-6)
    empty = integral == 0
    assert empty.any() and (~empty).any()
    np.testing.assert_array_equal(combined[:, :, 3], np.where(empty & transparent, 0.0, 1.0))


def test_xray_pass_only_when_enabled(blob_object):
    scene = bs.setup(32, 32, xray_pass=False)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=3.0)
    assert set(bs.render(scene)) == {"ViewLayer.Combined"}


@pytest.mark.parametrize("method", ['PCVR', 'BILINEAR_SPREAD'])
def test_subgrid_methods_approximate_exact(blob_object, method):
    scene = bs.setup(96, 96, method=method)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=2.2)
    image = bs.xray(bs.render(scene))
    reference = bs.exact(bs.world_grid(blob_object))
    # The subgrid methods trade accuracy for speed; they blur a little more than the kernel does.
    assert np.sqrt(np.mean((image - reference) ** 2)) / np.sqrt(np.mean(reference ** 2)) < 0.1


def test_status_line_from_native_statistics(blob_object):
    bs.setup(48, 48)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=3.0)
    stats = {}
    pn.render_xray(bs.world_grid(blob_object), bs.reference_camera(), stats=stats)
    line = statistics.format_stats(stats)
    assert f"Voxels {stats['voxels']:,}" in line and "px/voxel" in line and "Stride" in line
    assert statistics.format_stats({}) == "No volume in view"
    # The renderer's own choices zoomed out show: a coarser level, or the sub-pixels it averaged.
    assert "Level of detail" not in line and "Supersampled" not in line
    zoomed = statistics.format_stats({**stats, "level": 2, "supersampling": 16})
    assert zoomed.endswith("| Level of detail 2 | Supersampled 16 x 16")
