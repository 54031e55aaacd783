"""Blender scenes as users set them up (issue 41): a CT imported and rendered with the defaults, volumes made by
modifiers with PCVR settings of their own, Volume > Render > Space, and the defaults that make a good first
image (ambient occlusion of material volumes, the view transform of X-rays, the light of a scan, the status
line of a sampled render)."""

import math

import bpy
import numpy as np
import pcvr_native as pn
import pytest

import blender_scenes as bs
import lit_scenes as ls
import material_scenes as ms
import scan_files as sf
from pcvr_addon.io import image_io
from pcvr_addon.render import statistics
from pcvr_addon.scene import first_look
from test_cli import check, pcvr

AIR, FAT, WATER = -1000, -100, 0


def ct_values():
    """A small CT in Hounsfield units [slice, row, column]: air around a water block holding a fat core, so that
    the raw integral through the middle is negative."""
    values = np.full((10, 16, 16), AIR, dtype=np.int16)
    values[2:8, 3:13, 3:13] = WATER
    values[3:7, 6:10, 6:10] = FAT
    return values


def import_ct(tmp_path):
    files = sf.dicom_series(str(tmp_path / "ct"), ct_values() + 1024, pixel_spacing=(2.0, 2.0), step=(0, 0, 2.0),
                            intercept=-1024.0)
    result = bpy.ops.pcvr.import_volume(filepath=files[0], directory_for_vdb=str(tmp_path / "vdb"))
    assert result == {'FINISHED'}
    return bpy.context.view_layer.objects.active


def scan_lights(scene):
    return [obj for obj in scene.objects if obj.type == 'LIGHT']


# 1. A CT imported: an X-ray of it is a DRR, and no Combined pixel is negative, -inf or NaN


def test_an_imported_ct_renders_as_a_drr_lit_and_shown_plainly(tmp_path):
    scene = bs.setup(48, 32)
    scene.view_settings.view_transform = 'AgX'  # Blender's default
    obj = import_ct(tmp_path)
    assert obj.data["pcvr_units"] == "HU" and obj.data.pcvr.xray_values == 'HOUNSFIELD'
    assert scene.view_settings.view_transform == 'Standard'
    # One sun from the front (no camera yet: LPS puts the patient's anterior at -Y), a little above.
    (light,) = scan_lights(scene)
    shines = np.array(light.matrix_world.to_3x3()) @ (0.0, 0.0, -1.0)
    np.testing.assert_allclose(shines, np.array([0.0, 1.0, -first_look.LIGHT_ELEVATION]) /
                               math.hypot(1.0, first_look.LIGHT_ELEVATION), atol=1e-6)

    bpy.ops.pcvr.frame_volume()
    passes = bs.render(scene)
    integral, combined = bs.xray(passes), passes["ViewLayer.Combined"]
    assert integral.min() >= 0 and integral.max() > 0
    assert np.isfinite(combined).all() and combined[..., :3].min() >= 0

    obj.data.pcvr.xray_values = 'DENSITY'  # the raw Hounsfield units: negative through the fat and the water
    passes = bs.render(scene)
    integral, combined = bs.xray(passes), passes["ViewLayer.Combined"]
    assert integral.min() < 0
    assert np.isfinite(combined).all() and combined[..., :3].min() == 0.0

    import_ct(tmp_path)  # again: the light is aimed again, not added
    assert len(scan_lights(scene)) == 1


def test_frame_volume_aims_the_scan_light_with_the_camera(tmp_path):
    scene = bs.setup(48, 32)
    import_ct(tmp_path)
    bpy.ops.pcvr.frame_volume(view='LEFT')  # the camera looks along +X
    (light,) = scan_lights(scene)
    shines = np.array(light.matrix_world.to_3x3()) @ (0.0, 0.0, -1.0)
    assert shines[0] > 0.9 and shines[2] < -0.3


def test_a_negative_integral_shows_zero_and_automatic_exposure_ignores_it(tmp_path):
    scene = bs.setup(48, 48)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=3.0)
    values = bs.box()
    values[4:8] *= -3.0  # half the box below zero
    bs.add_volume("Signed", bs.write_vdb(tmp_path / "signed.vdb", values))
    scene.pcvr.xray_gain = 200.0  # exp(200 x 2.4) overflows: -inf before
    passes = bs.render(scene)
    integral, grey = bs.xray(passes), passes["ViewLayer.Combined"][..., 0]
    assert integral.min() < -1 and integral.max() > 0.5
    assert np.isfinite(grey).all() and grey[integral <= 0].max() == 0.0 and grey.max() > 0.99

    scene.pcvr.use_auto_exposure = True
    passes = bs.render(scene)
    integral, grey = bs.xray(passes), passes["ViewLayer.Combined"][..., 0]
    assert np.percentile(grey[integral > 0], 99) == pytest.approx(0.8, abs=0.01)  # passes.EXPOSURE_GREY
    assert grey[integral <= 0].max() == 0.0


def test_the_command_line_renders_a_vdb_in_hounsfield_units_as_a_drr(tmp_path):
    values = np.full((16, 16, 16), float(AIR), np.float32)
    values[4:12, 4:12, 4:12] = FAT
    ct = str(tmp_path / "ct.vdb")
    pn.Grid.from_dense(values, bs.centred(), background=float(AIR)).write_vdb(ct, "density",
                                                                            metadata={"pcvr_units": "HU"})

    def render(name, *options):
        # The paper's passband: the compensated one sharpens, below zero beside the edges.
        check(pcvr(ct, "-o", tmp_path / f"{name}.exr", "--view", "front", "--magnification", 1, "--passband", "paper",
                   *options))
        return image_io.read_passes(str(tmp_path / f"{name}.exr"))[""]

    default, asked = render("default"), render("asked", "--hounsfield")
    np.testing.assert_array_equal(default, asked)
    assert default[..., 4].min() >= 0 and default[..., 4].max() > 0  # fat: 0.9 mu_water
    raw = render("raw", "--no-hounsfield")
    assert raw[..., 4].min() < -50  # 0.8 units of -100 HU
    assert np.isfinite(raw).all() and raw[..., :3].min() == 0.0


def test_the_command_line_renders_a_converted_scan_in_millimetres(tmp_path):
    """A .vdb that convert wrote lies in millimetres: the command line's scene takes a unit for a millimetre, so a
    DRR through 100 mm of water integrates mu_water x 10 cm (in metres it integrated 1000 times that: white)."""
    from pcvr_addon import volume_import

    values = np.full((10, 50, 16), AIR, dtype=np.int16)  # [slice (z), row (y), column (x)], 2 mm voxels
    values[2:8, :, 4:12] = WATER  # 50 rows of 2 mm along y, the front view's axis
    files = sf.dicom_series(str(tmp_path / "ct"), values + 1024, pixel_spacing=(2.0, 2.0), step=(0, 0, 2.0),
                            intercept=-1024.0)
    volume_import.convert(files[0], str(tmp_path / "water.vdb"))
    check(pcvr(tmp_path / "water.vdb", "-o", tmp_path / "drr.exr", "--view", "front", "--magnification", 1))
    drr = image_io.read_passes(str(tmp_path / "drr.exr"))[""]
    centre = drr[drr.shape[0] // 2, drr.shape[1] // 2]
    assert centre[4] == pytest.approx(0.193 * 10.0, rel=0.02)
    assert 0.5 < centre[0] < 0.99  # the default gain shows it grey, not white


# 2. Volumes made by modifiers render with their Volume's PCVR settings


@pytest.fixture
def mesh_to_volume():
    """A Mesh to Volume volume of a unit cube spanning x, y in [0, 1], seen from above (48 px over 3 units)."""
    scene = bs.setup(48, 48)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=3.0)
    return scene, bs.add_mesh_to_volume((0.5, 0.5, 0.0), density=2.0)


def test_a_crop_box_cuts_a_mesh_to_volume_volume(mesh_to_volume):
    scene, obj = mesh_to_volume
    whole = bs.xray(bs.render(scene))
    crop = bpy.data.objects.new("Crop", None)
    crop.location, crop.scale = (0.25, 0.5, 0.0), (0.25, 1.0, 1.0)  # keeps x in [0, 0.5]
    scene.collection.objects.link(crop)
    obj.data.pcvr.crop_object, obj.data.pcvr.use_crop = crop, True
    cut = bs.xray(bs.render(scene))
    # Image columns: x = 0 at 24, 0.5 at 32, 1 at 40; rows: y = 0.5 at row 16.
    assert whole[16, 36] > 1.0 and cut[16, 36] == 0.0
    assert cut[16, 28] == pytest.approx(whole[16, 28], rel=1e-3)


def test_density_scale_and_grid_of_a_mesh_to_volume_volume(mesh_to_volume):
    scene, obj = mesh_to_volume
    whole = bs.xray(bs.render(scene))
    obj.data.pcvr.density_scale = 3.0
    np.testing.assert_allclose(bs.xray(bs.render(scene)), 3.0 * whole, rtol=1e-4, atol=1e-5 * whole.max())
    obj.data.pcvr.density_scale = 1.0
    obj.data.pcvr.grid = "no such grid"
    with pytest.raises(RuntimeError, match="no such grid"):
        bs.render(scene)


def test_a_geometry_nodes_volume_on_a_mesh_renders_with_the_defaults():
    """No Volume datablock to hold settings: the defaults, as docs/shaded-rendering-in-blender.md says."""
    from pcvr_addon.scene import volumes

    tree = bpy.data.node_groups.new("Volume Cube", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    tree.links.new(tree.nodes.new("GeometryNodeVolumeCube").outputs["Volume"],
                   tree.nodes.new("NodeGroupOutput").inputs[0])
    generator = bpy.data.objects.new("Generator", bpy.data.meshes.new("Generator"))
    generator.modifiers.new("Nodes", 'NODES').node_group = tree
    bpy.context.scene.collection.objects.link(generator)
    (source,) = volumes.in_view(bpy.context.evaluated_depsgraph_get())
    assert source.settings.density_scale == 1.0 and source.settings.source == 'TRANSFER_FUNCTION'


# 4. Volume > Render > Space


def material_alpha(tmp_path, rng, scale, space):
    """The alpha of a material volume scaled by `scale` (its Render > Space `space`), seen by a camera scaled with
    it: in Object space the same image at every scale."""
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    scene = ls.shaded_setup(48, 48)
    bs.add_camera(location=(0.0, 0.0, 5.0 * scale), ortho_scale=2.0 * scale)
    obj = bs.add_volume("Smoke", bs.write_vdb(tmp_path / "blob.vdb", bs.blob(rng)), scale=(scale,) * 3)
    ms.use_material(obj, ms.principled_material(Density=5.0))
    obj.data.render.space = space
    return ls.combined(bs.render(scene))[..., 3]


def test_object_space_keeps_a_scaled_material_volumes_look(tmp_path, rng):
    whole = material_alpha(tmp_path, rng, 1.0, 'OBJECT')
    assert whole.max() > 0.5
    for space in ('OBJECT', 'WORLD'):
        assert material_alpha(tmp_path, np.random.default_rng(20250101), 1.0, space) == pytest.approx(whole)
    small = material_alpha(tmp_path, np.random.default_rng(20250101), 0.4, 'OBJECT')
    # Everything scales with the object: the same image, up to single-precision rounding (measured 5.0e-4 of
    # alpha at most).
    assert np.abs(small - whole).max() < 2e-3
    world = material_alpha(tmp_path, np.random.default_rng(20250101), 0.4, 'WORLD')
    print(f"alpha kept at 0.4: {small.sum() / whole.sum():.4f} (Object), {world.sum() / whole.sum():.4f} (World)")
    assert world.sum() < 0.75 * whole.sum()  # per world unit: 0.4 of the optical depth


def test_object_space_along_the_view_for_a_non_uniform_scale():
    from pcvr_addon.scene.scene_inputs import object_units_per_world

    matrix = np.diag([2.0, 0.5, 4.0, 1.0])
    assert object_units_per_world(matrix, (0.0, 0.0, -3.0)) == pytest.approx(0.25)
    assert object_units_per_world(matrix, (0.0, 1.0, 0.0)) == pytest.approx(2.0)
    assert object_units_per_world(matrix) == pytest.approx(4 ** (-1 / 3))  # no view: the mean scale, det^(1/3)
    assert object_units_per_world(np.diag([0.4, 0.4, 0.4, 1.0]), (1.0, 2.0, 3.0)) == pytest.approx(2.5)


# 5. Defaults for a good first image


def test_octaves_from_light_paths_without_cycles_take_its_default_of_no_bounces():
    from types import SimpleNamespace

    from pcvr_addon.scene.scene_inputs import light_paths_octaves

    assert light_paths_octaves(SimpleNamespace()) == 1  # Cycles disabled: no scene.cycles
    assert light_paths_octaves(SimpleNamespace(cycles=SimpleNamespace(volume_bounces=3, max_bounces=12))) == 4


def test_ambient_occlusion_follows_scattering_until_set():
    """On where the volume scatters (Source: Material, the Scattering model), as Cycles shadows the world's light
    through a medium: measured against Cycles on the materials bench (docs/shaded-rendering-in-blender.md), Quick
    Smoke went from 45.5 to 62.9 dB, the CT head scattering from 39.8 to 49.7 dB. Off for Blinn-Phong."""
    settings = bpy.data.volumes.new("Smoke").pcvr
    assert not settings.ambient_occlusion
    settings.source = 'MATERIAL'
    assert settings.ambient_occlusion
    settings.source = 'TRANSFER_FUNCTION'
    assert not settings.ambient_occlusion
    settings.shading_model = 'SCATTER'
    assert settings.ambient_occlusion
    settings.ambient_occlusion = False  # the user's choice stays
    settings.shading_model = 'BLINN_PHONG'
    settings.source = 'MATERIAL'
    assert not settings.ambient_occlusion
    from pcvr_addon.scene import fluid_domain
    assert fluid_domain.default_settings().ambient_occlusion  # a fluid domain renders its material


def test_switching_to_xray_shows_it_through_the_standard_view_transform():
    scene = bpy.context.scene
    scene.pcvr.mode = 'SHADED'
    scene.view_settings.view_transform = 'AgX'
    scene.pcvr.mode = 'XRAY'
    assert scene.view_settings.view_transform == 'Standard'
    scene.pcvr.mode = 'SHADED'
    scene.view_settings.view_transform = 'Filmic' if 'Filmic' in _view_transforms(scene) else 'AgX'
    assert scene.view_settings.view_transform != 'Standard'  # shaded mode keeps the user's
    scene.view_settings.view_transform = 'False Color'
    scene.pcvr.mode = 'XRAY'
    assert scene.view_settings.view_transform == 'False Color'  # a choice other than tone mapping stays


def _view_transforms(scene):
    return {item.identifier for item in scene.view_settings.bl_rna.properties["view_transform"].enum_items}


def test_the_status_line_of_a_sampled_render_counts_the_samples():
    stats = {"voxels": 0, "sheet_samples": 123456, "blocks": 10, "blocks_outside": 1, "blocks_transparent": 2,
             "sheets": 40, "strides": [2], "seconds": 0.5, "grids_sampled": 1}
    line = statistics.format_sheet_stats(stats)
    assert line.startswith("Samples 123,456 |") and "Voxels" not in line
    assert statistics.format_sheet_stats({**stats, "voxels": 7}).startswith("Voxels 7 | Samples 123,456 |")
    assert statistics.format_sheet_stats({**stats, "sheet_samples": 0}).startswith("Voxels 0 |")
