"""Crop boxes and clip planes per volume: F12, the viewport, bad input, the operators; the command line's are in
test_cli_clipping.py.

The add-on's images are compared with pcvr_native's called directly with the clip numbers worked out by hand
(clip_scenes.py): the native cut itself is tested in tests/native."""

import math

import bpy
import numpy as np
import pytest

import blender_scenes as bs
import clip_scenes as cs
import lit_scenes as ls
import viewport_scenes as vs
from pcvr_addon.io import image_io
from pcvr_addon.render import prepared_scene, statistics
from pcvr_addon.scene import scene_inputs

SIZE = (48, 48)
# The F12 render and the reference make the same native call with the same grid and numbers: they differ only
# in the order threads add up a pixel, and in the clip numbers by Blender's single-precision matrices (a plane of
# a turned empty: 3.1e-5 of the maximum measured). Half a pixel's shift, or a cut a voxel off, costs over 10%.
SAME_CALL = 1e-4


@pytest.fixture
def blob(tmp_path, rng):
    """A lumpy volume at the origin seen from above by an orthographic camera, X-ray: (volume object, grid)."""
    bs.setup(*SIZE, method='REGULAR')
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=2.0)
    obj = bs.add_volume("Blob", bs.write_vdb(tmp_path / "blob.vdb", bs.blob(rng)))
    return obj, bs.world_grid(obj)


def rendered_xray():
    return bs.xray(bs.render())


def native_xray(grids, **clip):
    import pcvr_native as pn
    return pn.render_xray(grids, bs.reference_camera(), method="regular", passband=bpy.context.scene.pcvr.passband.lower(),
                          **clip)


def share_kept(image, grids):
    """The share of the uncut X-ray's integral that `image` keeps."""
    return image.sum() / native_xray(grids).sum()


def test_crop_object_keeps_its_box(blob):
    obj, grid = blob
    # Any object crops: a turned, unevenly scaled empty keeping about the right half of the volume.
    centre, half_sizes, angle = (0.45, 0.05, 0.0), (0.5, 0.9, 0.9), 0.3
    cs.crop(obj, cs.add_empty("Box", location=centre, rotation=(0.0, 0.0, angle), scale=half_sizes))
    image = rendered_xray()
    bs.assert_matches(image, native_xray(grid, clip_box=cs.world_to_box(centre, half_sizes, angle)), SAME_CALL)
    assert 0.3 < share_kept(image, grid) < 0.7


def test_clip_plane_keeps_its_local_z_side(blob):
    obj, grid = blob
    # Turned a quarter about Y, the empty's local +Z is world +X: x >= 0.05 is kept, whatever its scale.
    cs.add_clip_plane(obj, cs.add_empty("Plane", 'SINGLE_ARROW', location=(0.05, 0.3, -0.2),
                                        rotation=(0.0, math.pi / 2, 0.0), scale=(2.0, 0.5, 3.0)))
    image = rendered_xray()
    bs.assert_matches(image, native_xray(grid, clip_planes=[(1.0, 0.0, 0.0, -0.05)]), SAME_CALL)
    # Columns left of x = 0.05 by more than the kernel's reach (2 voxels of 0.1) see nothing: pixels are 1/24 wide.
    assert image[:, :19].max() == 0 and image[:, 30:].max() > 0

    obj.data.pcvr.clip_planes[0].enabled = False
    bs.assert_matches(rendered_xray(), native_xray(grid), SAME_CALL)


@pytest.fixture
def two_volumes(tmp_path, rng):
    """Two lumpy volumes side by side, "Left" cropped to its right half by a box, "Right" not; transparent film.
    Returns (left, right) objects."""
    bs.setup(*SIZE, method='REGULAR')
    bpy.context.scene.render.film_transparent = True
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=2.5)
    filepath = bs.write_vdb(tmp_path / "blob.vdb", bs.blob(rng))
    left = bs.add_volume("Left", filepath, location=(-0.5, 0.0, 0.0))
    right = bs.add_volume("Right", filepath, location=(0.5, 0.0, 0.0))
    right.data = bpy.data.volumes.new("Right")   # settings of its own, the same file
    right.data.filepath = filepath
    cs.crop(left, cs.add_empty("Box", location=(-0.25, 0.0, 0.0), scale=(0.25, 1.0, 1.0)))
    return left, right


def test_each_volume_has_its_own_crop(two_volumes):
    left, right = two_volumes
    boxes = [cs.world_to_box((-0.25, 0.0, 0.0), (0.25, 1.0, 1.0)), None]
    bs.assert_matches(rendered_xray(), native_xray([bs.world_grid(left), bs.world_grid(right)], clip_box=boxes),
                      SAME_CALL)


@pytest.mark.parametrize("mode", ['SHADED', 'MIP'])
def test_each_volume_has_its_own_crop_in_sheet_modes(two_volumes, mode):
    left, right = two_volumes
    bpy.context.scene.pcvr.mode = mode
    for obj in two_volumes:
        ls.set_ramp(obj)
    cropped = ls.combined(bs.render())
    left.data.pcvr.use_crop = False
    whole = ls.combined(bs.render())
    alpha, whole_alpha = cropped[..., 3], whole[..., 3]
    # Pixels are 2.5 / 48 wide, column c centred at x = (c + 0.5) 2.5 / 48 - 1.25. The left volume shows from x =
    # -1.05 and its crop keeps x > -0.5 (column 14 on; the cut is exact, no kernel reaches across): columns 4 to 11
    # show it whole only; from column 30 (x > 0.34) only the right volume shows.
    assert whole_alpha[:, 4:12].max() > 0.2 and alpha[:, 4:12].max() == 0 and alpha[:, 14:22].max() > 0.5
    np.testing.assert_allclose(cropped[:, 30:], whole[:, 30:], atol=1e-6)


# -------------------------------------------------------------------------------------------------
# Bad input: the volume is left out, named with its object and the cause; the others render

def _zero_scale_crop(obj):
    cs.crop(obj, cs.add_empty("Box", scale=(1.0, 0.0, 1.0)))
    return r"crop object 'Box' is scaled to zero"


def _nan_crop(obj):
    cs.crop(obj, cs.add_empty("Box", location=(0.0, float("nan"), 0.0)))
    return r"crop object 'Box': its world matrix holds numbers that are not finite"


def _zero_scale_plane(obj):
    cs.add_clip_plane(obj, cs.add_empty("Plane", 'SINGLE_ARROW', scale=(0.0, 0.0, 0.0)))
    return r"clip plane 'Plane' is scaled to zero"


def _no_crop_object(obj):
    obj.data.pcvr.use_crop = True
    return r"a crop object is missing"


def _deleted_crop(obj):
    box = cs.crop(obj, cs.add_empty("Box", scale=(0.5, 0.5, 0.5)))
    bs.render()  # renders the crop
    with bpy.context.temp_override(selected_objects=[box], active_object=box):
        bpy.ops.object.delete()   # as the X key: the pointer keeps the object alive, in no collection
    return r"crop object 'Box' was deleted"


@pytest.mark.parametrize("make_bad", [_zero_scale_crop, _nan_crop, _zero_scale_plane, _no_crop_object, _deleted_crop],
                         ids=lambda make_bad: make_bad.__name__[1:])
def test_bad_clipping_leaves_the_volume_out_and_others_render(tmp_path, rng, make_bad):
    bs.setup(*SIZE, method='REGULAR')
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=3.0)
    filepath = bs.write_vdb(tmp_path / "blob.vdb", bs.blob(rng))
    good = bs.add_volume("Good", filepath, location=(-0.5, 0.0, 0.0))
    bad = bs.add_volume("Bad", bs.write_vdb(tmp_path / "bad.vdb", bs.blob(rng)), location=(0.5, 0.0, 0.0))
    cause = make_bad(bad)
    with pytest.raises(RuntimeError, match=f"Volume object 'Bad': {cause}"):
        bpy.ops.render.render(write_still=False)
    bs.assert_matches(bs.xray(image_io.render_result_passes(bpy.context.scene)), native_xray(bs.world_grid(good)),
                      SAME_CALL)


# -------------------------------------------------------------------------------------------------
# The viewport

def test_viewport_renders_again_when_the_crop_object_moves(blob, monkeypatch):
    obj, grid = blob
    draws = vs.record_draws(monkeypatch)
    prepares = []
    prepare = prepared_scene.prepare
    monkeypatch.setattr(prepared_scene, "prepare",
                        lambda inputs, *args: prepares.append(inputs) or prepare(inputs, *args))
    engine = vs.StandInEngine()
    try:
        box = cs.crop(obj, cs.add_empty("Box", location=(0.5, 0.0, 0.0), scale=(0.5, 1.0, 1.0)))
        context = vs.camera_context(bpy.context.scene.camera, *SIZE)
        engine.settle(context)
        before = engine.renderer.latest().pixels
        box.location.x -= 0.3
        engine.settle(context)
        image = engine.renderer.latest()
        assert image.step.scale == 1 and draws[-1][0] is image.pixels
        assert not np.array_equal(image.pixels, before)
        np.testing.assert_array_equal(image.pixels, ls.combined(bs.render()))
        assert len(prepares) == 2   # the viewport's first and F12's: the cut re-used the viewport's grid and objects
        obj.location.x += 0.1
        engine.settle(context)
        assert len(prepares) == 3
    finally:
        engine.free()


# -------------------------------------------------------------------------------------------------
# The operators, and what the scene reads of their objects

def read_clipping(obj):
    inputs, _display = scene_inputs.read(bpy.context.evaluated_depsgraph_get(), prepared_scene.export_grid)
    volume = next(volume for volume in inputs.volumes if volume.name == obj.name)
    assert volume.error == ""
    return volume.clipping


def world_corners(matrix, lo, hi):
    corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    return (np.asarray(matrix) @ corners.T)[:3].T


def test_add_crop_box_fits_the_volume_and_moves_with_it(blob):
    obj, _grid = blob
    obj.location, obj.scale = (0.3, -0.2, 0.1), (2.0, 1.0, 1.0)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.pcvr.add_crop_box() == {'FINISHED'}
    box = obj.data.pcvr.crop_object
    assert obj.data.pcvr.use_crop and box.empty_display_type == 'CUBE' and box.parent == obj
    assert bpy.context.view_layer.objects.active == box   # to be moved right away
    bpy.context.evaluated_depsgraph_get()
    bounds = np.array([tuple(corner) for corner in obj.bound_box])
    # The cube's corners are the volume's bounding box in the world.
    np.testing.assert_allclose(world_corners(box.matrix_world, (-1, -1, -1), (1, 1, 1)),
                               world_corners(obj.matrix_world, bounds.min(axis=0), bounds.max(axis=0)), atol=1e-6)
    np.testing.assert_allclose(read_clipping(obj).box, np.linalg.inv(np.array(box.matrix_world)), atol=1e-6)

    box_to_world = np.array(box.matrix_world)
    obj.location.x += 1.0   # a child: the box goes along
    bpy.context.evaluated_depsgraph_get()
    box_to_world[0, 3] += 1.0
    np.testing.assert_allclose(read_clipping(obj).box, np.linalg.inv(box_to_world), atol=1e-6)


def test_add_and_remove_clip_planes(blob):
    obj, _grid = blob
    obj.location = (0.3, -0.2, 0.1)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.pcvr.add_clip_plane() == {'FINISHED'}
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.pcvr.add_clip_plane() == {'FINISHED'}
    settings = obj.data.pcvr
    first, second = (item.object for item in settings.clip_planes)
    second.rotation_euler.x = math.pi   # its +Z now points down
    bpy.context.evaluated_depsgraph_get()
    bounds = np.array([tuple(corner) for corner in obj.bound_box])
    centre = world_corners(obj.matrix_world, bounds.mean(axis=0), bounds.mean(axis=0))[0]
    # Both through the volume's centre: the first keeps what is above it, the second what is below.
    expected = [(0.0, 0.0, 1.0, -centre[2]), (0.0, 0.0, -1.0, centre[2])]
    np.testing.assert_allclose(read_clipping(obj).planes, expected, atol=1e-6)

    settings.clip_plane_index = 0
    with bpy.context.temp_override(volume=obj.data):
        assert bpy.ops.pcvr.remove_clip_plane() == {'FINISHED'}
    assert [item.object for item in settings.clip_planes] == [second] and first.name in bpy.data.objects
    np.testing.assert_allclose(read_clipping(obj).planes, expected[1:], atol=1e-6)


def test_last_render_rows_show_what_clipping_cut():
    xray = {"voxels": 10, "magnification": 1.0, "magnification_max": 2.0, "strides": [1.5], "seconds": 0.1}
    assert "Blocks cut away" not in dict(statistics.statistics_rows('XRAY', {**xray, "blocks_clipped": 0}))
    rows = dict(statistics.statistics_rows('XRAY', {**xray, "blocks_clipped": 1200, "voxels_cut": 34}))
    assert (rows["Blocks cut away"], rows["Voxels cut through"], rows["Voxels"]) == ("1,200", "34", "10")
