"""Shaded mode: the engine hands pcvr_native.render_shaded the scene's volume, transfer function, lights,
world and camera; lights move the shading; the film's Transparent option; the Depth pass."""

import math

import bpy
import numpy as np
import pcvr_native as pn
import pytest

import blender_scenes as bs
import lit_scenes as ls
from pcvr_addon.render import statistics
from pcvr_addon.render.passes import BACKGROUND_DEPTH


@pytest.fixture
def blob_object(tmp_path, rng):
    obj = bs.add_volume("Blob", bs.write_vdb(tmp_path / "blob.vdb", bs.blob(rng)), rotation=(0.3, 0.2, 0.5))
    ls.set_ramp(obj)
    return obj


def lit_blob_scene(blob_object, transparent=True):
    """The blob lit by a sun, a point light and a grey-blue world, seen by a tilted orthographic camera."""
    scene = ls.shaded_setup(64, 48, transparent=transparent)
    camera = bs.add_camera(location=(0.5, -3.0, 3.0), ortho_scale=2.4)
    camera.rotation_euler = (-camera.location).to_track_quat('-Z', 'Y').to_euler()
    ls.add_light('SUN', rotation=(0.7, -0.4, 0.3), power=4.0, color=(1.0, 0.875, 0.75))
    ls.add_light('POINT', location=(-1.0, -1.5, 1.0), power=300.0)
    ls.set_world(WORLD)
    settings = blob_object.data.pcvr
    settings.ambient, settings.diffuse, settings.specular, settings.shininess = 0.25, 0.75, 0.375, 20.0
    return scene


def lit_blob_lights():
    """lit_blob_scene's lights as render_shaded takes them (Blender's sun irradiance over pi, its point power over
    4 pi^2)."""
    return [pn.Light.sun(ls.sun_direction((0.7, -0.4, 0.3)), color=(1.0, 0.875, 0.75), strength=4.0 / math.pi),
            pn.Light.point((-1.0, -1.5, 1.0), strength=300.0 / (4 * math.pi ** 2))]


# Numbers that single precision (Blender's colours and settings) holds exactly, so that the references below
# get the very same inputs.
WORLD = (0.125, 0.1875, 0.25)
# Relative to the image's maximum: single-precision noise (see test_shaded_render_equals_render_shaded).
TOLERANCE = 1e-5


def reference(blob_object):
    """pcvr_native.render_shaded called directly with what lit_blob_scene holds, the light conversion of
    docs/shaded-rendering-in-blender.md written out: sun strength / pi, point power / (4 pi^2)."""
    lights = lit_blob_lights()
    return pn.render_shaded(bs.world_grid(blob_object), bs.reference_camera(), ls.reference_transfer_function(),
                            lights=lights, ambient=WORLD, method="regular",
                            shading=pn.Shading(ambient=0.25, diffuse=0.75, specular=0.375, shininess=20.0))


def test_shaded_render_equals_render_shaded(blob_object):
    scene = lit_blob_scene(blob_object)
    image = ls.combined(bs.render(scene))
    expected = reference(blob_object)
    assert expected[..., 3].max() > 0.9 and (expected[..., 3] == 0).any(), "the test scene shows too little"
    # The same call with the same numbers, but for the camera matrix, which Blender's render and the reference
    # derive in different single-precision steps (2.7e-8 apart), and the ramp's single-precision positions;
    # the renderer's single-precision sample positions turn that into differences of 3.3e-6 of the image's
    # maximum at most (measured).
    np.testing.assert_allclose(image, expected, atol=TOLERANCE * expected.max())


def test_opaque_film_shows_the_world_behind(blob_object):
    scene = lit_blob_scene(blob_object, transparent=False)
    image = ls.combined(bs.render(scene))
    expected = reference(blob_object)
    behind = (1 - expected[..., 3:]) * np.array(WORLD, dtype=np.float32)
    np.testing.assert_allclose(image[..., :3], expected[..., :3] + behind, atol=TOLERANCE * expected.max())
    assert (image[..., 3] == 1).all()


def test_transparent_film_is_clear_away_from_the_volume(tmp_path):
    scene = ls.shaded_setup(48, 48)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=3.0)
    obj = bs.add_volume("Box", bs.write_vdb(tmp_path / "box.vdb", bs.box()))
    ls.set_ramp(obj, tf_range=(0.0, 1.0))
    ls.add_light('SUN', power=3.0)
    ls.set_world((0.3, 0.3, 0.3))
    alpha = ls.combined(bs.render(scene))[..., 3]
    # 48 px over 3 units: the box spans 0.8 units (13 px) in the middle, its kernels 0.2 more on each side.
    assert alpha[24, 24] > 0.9
    inside = np.zeros_like(alpha, dtype=bool)
    inside[14:34, 14:34] = True
    assert (alpha[~inside] == 0).all()


def brightness_centroid(image, axis):
    """Where along `axis` (1: columns, left to right) the light falls, in pixels."""
    weight = image[..., :3].sum(axis=2)
    profile = weight.sum(axis=1 - axis)
    return float((profile * np.arange(len(profile))).sum() / profile.sum())


def test_turning_the_sun_moves_the_light(tmp_path):
    """A sphere of fog lit from the left is brighter on its left, and from the right on its right."""
    scene = ls.shaded_setup(64, 64)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=2.0)
    values = np.zeros((16, 16, 16), np.float32)
    i = np.indices(values.shape) - 7.5
    values[(i ** 2).sum(axis=0) < 36] = 1.0
    obj = bs.add_volume("Ball", bs.write_vdb(tmp_path / "ball.vdb", values))
    ls.set_ramp(obj, ramp=[(0.0, (1, 1, 1, 0)), (1.0, (1, 1, 1, 0.9))], tf_range=(0.0, 1.0))
    sun = ls.add_light('SUN', power=math.pi)

    centroids = []
    for angle in (-1.0, 1.0):  # light travelling right (from the left) and then left
        sun.rotation_euler = (0.0, angle, 0.0)
        image = ls.combined(bs.render(scene))
        centroids.append(brightness_centroid(image, axis=1))
    alpha_centre = brightness_centroid(np.repeat(image[..., 3:], 3, axis=2), axis=1)
    # Measured: 6.5 pixels either side of the silhouette's centre (the ball is 38 pixels wide).
    assert centroids[0] < alpha_centre - 3 and centroids[1] > alpha_centre + 3


def test_depth_pass_is_the_depth_of_a_slab(tmp_path):
    """An opaque slab whose top face is 1.0 below a camera looking straight down: the Depth pass holds 1.0,
    to within a voxel (0.1), where the slab is, and the background depth elsewhere."""
    scene = ls.shaded_setup(48, 48)
    bpy.context.view_layer.use_pass_z = True
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=3.0)
    values = np.zeros((16, 16, 16), np.float32)
    values[2:14, 2:14, 4:8] = 1.0  # voxel centres z = -0.35 .. -0.05 of the centred grid: top face at 0.0
    obj = bs.add_volume("Slab", bs.write_vdb(tmp_path / "slab.vdb", values), location=(0.0, 0.0, 4.0))
    ls.set_ramp(obj, ramp=[(0.0, (1, 1, 1, 0)), (1.0, (1, 1, 1, 0.95))], tf_range=(0.0, 1.0))
    passes = bs.render(scene)
    depth, alpha = passes["ViewLayer.Depth"][..., 0], ls.combined(passes)[..., 3]
    top_depth = 5.0 - 4.0  # the camera at z 5, the slab's top face at z 4
    covered = alpha > 0.99
    assert covered.sum() > 100
    # Measured: 1.05, the depth of the first sample past opacity one half, half a voxel into the slab.
    assert np.abs(depth[covered] - top_depth).max() < 0.1
    assert (depth[alpha < 0.5] == BACKGROUND_DEPTH).all()
    assert (alpha < 0.5).any()


def test_depth_pass_only_in_shaded_mode_with_z(blob_object):
    scene = ls.shaded_setup(32, 32)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=3.0)
    assert "ViewLayer.Depth" not in bs.render(scene)
    bpy.context.view_layer.use_pass_z = True
    assert "ViewLayer.Depth" in bs.render(scene)
    scene.pcvr.mode = 'XRAY'
    assert "ViewLayer.Depth" not in bs.render(scene)


def test_xray_pass_in_shaded_mode(blob_object):
    scene = ls.shaded_setup(48, 48)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=2.5)
    bpy.context.view_layer.pcvr.use_pass_xray = True
    bs.assert_matches(bs.xray(bs.render(scene)), bs.exact(bs.world_grid(blob_object)))


def test_volume_without_shading_shows_its_colours(blob_object):
    scene = ls.shaded_setup(48, 48)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=2.5)
    ls.add_light('SUN', power=10.0)
    blob_object.data.pcvr.use_shading = False
    image = ls.combined(bs.render(scene))
    expected = pn.render_shaded(bs.world_grid(blob_object), bs.reference_camera(), ls.reference_transfer_function(),
                                ambient=(1, 1, 1), shading=pn.Shading(ambient=1, diffuse=0, specular=0), method="regular")
    np.testing.assert_allclose(image, expected, atol=TOLERANCE * expected.max())


def test_a_scattering_volume_renders_as_render_shaded_with_its_phase_function(blob_object):
    scene = lit_blob_scene(blob_object)
    blob_object.data.pcvr.shading_model, blob_object.data.pcvr.anisotropy = 'SCATTER', 0.5
    image = ls.combined(bs.render(scene))
    lights = lit_blob_lights()
    expected = pn.render_shaded(bs.world_grid(blob_object), bs.reference_camera(), ls.reference_transfer_function(),
                                lights=lights, ambient=WORLD, method="regular",
                                # the world's light shadowed, as a scattering volume has it by default, and
                                # single scattering, as Cycles' default of 0 volume bounces
                                shading=pn.Shading(model="scatter", anisotropy=0.5, ambient_occlusion=True,
                                                   scattering_octaves=1))
    assert expected[..., 3].max() > 0.9
    np.testing.assert_allclose(image, expected, atol=TOLERANCE * expected.max())
    # Not Blinn-Phong's image: the model reached the renderer.
    assert np.abs(image - reference(blob_object)).max() > 0.05 * expected.max()


def scattering_blob(blob, octaves):
    """render_shaded's image of the lit blob scattering at anisotropy 0.5 with `octaves`, shadows and ambient
    occlusion on (a scattering volume's default)."""
    return pn.render_shaded(bs.world_grid(blob), bs.reference_camera(), ls.reference_transfer_function(),
                            lights=lit_blob_lights(), ambient=WORLD, method="regular", shadows=True,
                            shading=pn.Shading(model="scatter", anisotropy=0.5, scattering_octaves=octaves,
                                               ambient_occlusion=True))


def test_scattering_octaves_reach_render_shaded(blob_object):
    scene = lit_blob_scene(blob_object)
    scene.pcvr.shadows = True
    settings = blob_object.data.pcvr
    settings.shading_model, settings.anisotropy, settings.scattering_octaves = 'SCATTER', 0.5, 2
    scene.cycles.volume_bounces = 0  # an explicit number overrides the Light Paths
    image = ls.combined(bs.render(scene))
    expected = scattering_blob(blob_object, 2)
    np.testing.assert_allclose(image, expected, atol=TOLERANCE * expected.max())
    # The octaves reached the renderer: they brighten the blob's shade.
    assert image[..., :3].sum() > 1.01 * scattering_blob(blob_object, 1)[..., :3].sum()
    mode, stats = statistics.last_render[scene.session_uid]
    assert dict(statistics.statistics_rows(mode, stats))["Scattering octaves"] == "2"
    assert "Multiple scattering (2 octaves)" in statistics.status_line(mode, stats)


def test_scattering_octaves_follow_cycles_volume_bounces_by_default(blob_object):
    """Octaves 0 (the default) render as Cycles would the scene's Light Paths: its default of 0 Volume Bounces
    scatters once, each bounce adds an octave, Total caps them."""
    scene = lit_blob_scene(blob_object)
    scene.pcvr.shadows = True
    settings = blob_object.data.pcvr
    assert settings.scattering_octaves == 0
    settings.shading_model, settings.anisotropy = 'SCATTER', 0.5
    for volume_bounces, total, octaves in ((0, 12, 1), (2, 12, 3), (64, 12, 6), (64, 1, 2)):
        scene.cycles.volume_bounces, scene.cycles.max_bounces = volume_bounces, total
        image = ls.combined(bs.render(scene))
        expected = scattering_blob(blob_object, octaves)
        np.testing.assert_allclose(image, expected, atol=TOLERANCE * expected.max(), err_msg=f"{volume_bounces}")
        mode, stats = statistics.last_render[scene.session_uid]
        assert stats["scattering_octaves"] == octaves


def test_ambient_occlusion_reaches_render_shaded(blob_object):
    scene = lit_blob_scene(blob_object)
    blob_object.data.pcvr.ambient_occlusion = True
    image = ls.combined(bs.render(scene))
    lights = lit_blob_lights()
    expected = pn.render_shaded(bs.world_grid(blob_object), bs.reference_camera(), ls.reference_transfer_function(),
                                lights=lights, ambient=WORLD, method="regular",
                                shading=pn.Shading(ambient=0.25, diffuse=0.75, specular=0.375, shininess=20.0,
                                                   ambient_occlusion=True))
    np.testing.assert_allclose(image, expected, atol=TOLERANCE * expected.max())
    # Only the world's light is taken away, and some of it is.
    plain = reference(blob_object)
    assert np.all(image[..., :3] <= plain[..., :3] + TOLERANCE * plain.max())
    assert image[..., :3].sum() < 0.99 * plain[..., :3].sum()


def test_each_volume_has_its_own_material(tmp_path, rng):
    """Two blobs side by side, one unshaded and one shiny: together they look as each does alone."""
    path = bs.write_vdb(tmp_path / "blob.vdb", bs.blob(rng))
    flat, shiny = (bs.add_volume(name, path, location=(x, 0, 0)) for name, x in (("Flat", -0.9), ("Shiny", 0.9)))
    for obj in (flat, shiny):
        ls.set_ramp(obj)
    flat.data.pcvr.use_shading = False
    shiny.data.pcvr.diffuse, shiny.data.pcvr.specular, shiny.data.pcvr.shininess = 0.5, 1.0, 40.0
    scene = ls.shaded_setup(96, 48)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=4.0)
    ls.add_light('SUN', rotation=(0.5, -0.3, 0.0), power=3.0)
    both = ls.combined(bs.render(scene))
    alone = []
    for shown, hidden in ((flat, shiny), (shiny, flat)):
        hidden.hide_render, shown.hide_render = True, False
        alone.append(ls.combined(bs.render(scene)))
    assert min(image[..., 3].max() for image in alone) > 0.5
    np.testing.assert_allclose(both, alone[0] + alone[1], atol=TOLERANCE * both.max())


def test_status_and_statistics_of_the_last_render(blob_object):
    scene = ls.shaded_setup(48, 48)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=2.5)
    bs.render(scene)
    mode, stats = statistics.last_render[scene.session_uid]
    assert mode == 'SHADED' and stats["voxels"] > 0 and stats["grids_sampled"] == 0  # regular splatting
    rows = dict(statistics.statistics_rows(mode, stats))
    assert rows["Voxels splatted"] == f"{stats['voxels']:,}" and "Transparent" in rows
    assert rows["Tiles"] == f"{stats['tiles']:,} of {stats['tile_size']} px"
    assert rows["Transparent voxels"].startswith(f"{stats['voxels_transparent']:,} (")
    assert "Culled blocks" in statistics.format_sheet_stats(stats)
    # The blob's voxels are cubes: world sheets. Anisotropic voxels' sheets follow their metric, and say so.
    assert stats["sheet_metric"] == "world" and "metric" not in statistics.format_sheet_stats(stats)
    assert "Sheets in the voxels' metric" in statistics.format_sheet_stats({**stats, "sheet_metric": "voxels"})
    # Post-convolved at this magnification, the automatic choice samples the sheets, and the last-render line says so.
    scene.pcvr.method = 'PCVR'
    bs.render(scene)
    mode, stats = statistics.last_render[scene.session_uid]
    assert stats["grids_sampled"] == 1 and stats["voxels"] == 0 and stats["sheet_samples"] > 0
    assert "Sheets sampled (1 volume" in statistics.format_sheet_stats(stats)
    rows = dict(statistics.statistics_rows(mode, stats))
    assert rows["Sheets sampled"].startswith(f"1 volume(s), {stats['sheet_samples']:,} values")
    assert rows["Sheets sampled"].endswith(f"subgrid strides {statistics.format_strides(stats['sampled_strides'])}")
    # Sheets on which a voxel spans several pixels are sampled on a subgrid, and the line says at which strides.
    line = statistics.format_sheet_stats({**stats, "sampled_strides": [1, 2, 3]})
    assert "Sheets sampled (1 volume, post-convolved at stride 2, 3)" in line
