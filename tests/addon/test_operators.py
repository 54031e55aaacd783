"""pcvr.frame_volume: an orthographic camera from one of Blender's views (the front by default), the volume fitted in
the scene's resolution, or (Set Resolution) at a given number of pixels per voxel."""

import bpy
import numpy as np
import pcvr_native as pn
import pytest

import blender_scenes as bs


@pytest.fixture
def box_object(tmp_path):
    obj = bs.add_volume("Box", bs.write_vdb(tmp_path / "box.vdb", bs.box()))
    bpy.context.view_layer.objects.active = obj
    return obj


def test_one_voxel_spans_magnification_pixels(box_object):
    scene = bs.setup()
    bpy.ops.pcvr.frame_volume(magnification=4.0, view='TOP', set_resolution=True)
    # 8 active voxels and 2 voxels of room for the kernel on each side.
    assert (scene.render.resolution_x, scene.render.resolution_y) == (48, 48)
    if hasattr(pn, "effective_magnification"):
        low, high = pn.effective_magnification(bs.world_grid(box_object), bs.reference_camera())
        assert low == pytest.approx(4.0) and high == pytest.approx(4.0)

    before = bs.xray(bs.render(scene))
    box_object.location.x += 0.1  # one voxel
    after = bs.xray(bs.render(scene))
    assert before.max() > 0
    # Single-precision splatting: equal up to rounding.
    np.testing.assert_allclose(after[:, 4:], before[:, :-4], rtol=1e-4, atol=1e-5 * before.max())


def test_creates_an_orthographic_camera_looking_down(box_object):
    scene = bpy.context.scene
    assert scene.camera is None
    bpy.ops.pcvr.frame_volume(magnification=2.0, view='TOP', set_resolution=True)
    camera = scene.camera
    assert camera.data.type == 'ORTHO'
    view = np.array(camera.matrix_world)[:3, :3] @ (0.0, 0.0, -1.0)
    np.testing.assert_allclose(view, (0.0, 0.0, -1.0))
    assert (scene.render.resolution_x, scene.render.resolution_y) == (24, 24)
    # Centred on the active voxels, which sit around the origin (index 7.5 of 0..15).
    np.testing.assert_allclose(np.array(camera.location)[:2], (0.0, 0.0), atol=1e-6)


def test_reports_a_non_volume():
    mesh = bpy.data.objects.new("Mesh", bpy.data.meshes.new("Mesh"))
    bpy.context.scene.collection.objects.link(mesh)
    bpy.context.view_layer.objects.active = mesh
    with pytest.raises(RuntimeError, match="not a volume"):
        bpy.ops.pcvr.frame_volume()


def test_reports_an_unreadable_volume(tmp_path):
    obj = bs.add_volume("Lost", tmp_path / "lost.vdb")
    bpy.context.view_layer.objects.active = obj
    with pytest.raises(RuntimeError, match="Lost.*lost.vdb"):
        bpy.ops.pcvr.frame_volume()


@pytest.mark.parametrize("view, looks_along, up", [
    ('TOP', (0, 0, -1), (0, 1, 0)),
    ('BOTTOM', (0, 0, 1), (0, -1, 0)),
    ('FRONT', (0, 1, 0), (0, 0, 1)),
    ('BACK', (0, -1, 0), (0, 0, 1)),
    ('RIGHT', (-1, 0, 0), (0, 0, 1)),
    ('LEFT', (1, 0, 0), (0, 0, 1)),
])
def test_numpad_views(box_object, view, looks_along, up):
    """Each of Blender's numpad views looks along its axis with its up, frames the volume whole and keeps one
    voxel at `magnification` pixels; the X-ray of the cube is the same square from every side."""
    scene = bs.setup()
    bpy.ops.pcvr.frame_volume(magnification=4.0, view=view, set_resolution=True)
    rotation = np.array(bpy.context.scene.camera.matrix_world)[:3, :3]
    np.testing.assert_allclose(rotation @ (0.0, 0.0, -1.0), looks_along, atol=1e-6)  # Blender keeps float32
    np.testing.assert_allclose(rotation @ (0.0, 1.0, 0.0), up, atol=1e-6)
    assert (scene.render.resolution_x, scene.render.resolution_y) == (48, 48)
    low, high = pn.effective_magnification(bs.world_grid(box_object), bs.reference_camera())
    assert low == pytest.approx(4.0) and high == pytest.approx(4.0)
    image = bs.xray(bs.render(scene))
    bs.assert_matches(image, bs.exact(bs.world_grid(box_object)))


def test_any_view_direction_frames_the_whole_volume(box_object):
    """An oblique direction (the isometric view, and one given as a vector): every voxel in the image, none cut."""
    scene = bs.setup()
    for arguments in ({"view": 'ISO'}, {"view": 'DIRECTION', "direction": (0.3, -0.8, -0.2)}):
        bpy.ops.pcvr.frame_volume(magnification=3.0, **arguments)
        image = bs.xray(bs.render(scene))
        assert image.max() > 0
        # Nothing reaches the image's border rows and columns: the kernels of the outermost voxels fit.
        border = np.concatenate([image[0], image[-1], image[:, 0], image[:, -1]])
        assert np.abs(border).max() < 1e-3 * image.max()


def test_a_zero_view_direction_is_reported(box_object):
    bs.setup()
    with pytest.raises(RuntimeError, match="view direction needs a length"):
        bpy.ops.pcvr.frame_volume(view='DIRECTION', direction=(0.0, 0.0, 0.0))


def test_by_default_keeps_the_resolution_and_looks_from_the_front(box_object):
    """Without Set Resolution the scene's resolution stays (a wide image here) and the volume fits in it whole;
    the default view is Blender's front (numpad 1), which a scan in LPS faces."""
    scene = bs.setup(width=80, height=40)
    scene.render.resolution_percentage = 50
    bpy.ops.pcvr.frame_volume()
    assert (scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage) == (80, 40, 50)
    rotation = np.array(scene.camera.matrix_world)[:3, :3]
    np.testing.assert_allclose(rotation @ (0.0, 0.0, -1.0), (0.0, 1.0, 0.0), atol=1e-6)
    # The box's 0.8 units and the kernels' 0.4 of room fill the image's height (the shorter side): 1.2 units
    # over 40 pixels, and the ortho scale spans the width, twice that.
    assert scene.camera.data.ortho_scale == pytest.approx(2 * 1.2)
    scene.render.resolution_percentage = 100
    image = bs.xray(bs.render(scene))
    assert image.max() > 0
    border = np.concatenate([image[0], image[-1], image[:, 0], image[:, -1]])
    assert np.abs(border).max() < 1e-3 * image.max()
    # Pixels are square: the box is as wide as it is high in the image.
    columns, rows = np.flatnonzero(image.max(axis=0) > 0.5 * image.max()), np.flatnonzero(image.max(axis=1) > 0.5 * image.max())
    assert abs(len(columns) - len(rows)) <= 1
