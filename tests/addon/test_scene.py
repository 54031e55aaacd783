"""Scene translation: which volumes a render reads, from where, and how often."""

import os
import tempfile

import bpy
import numpy as np
import pytest

import blender_scenes as bs
from pcvr_addon.io import image_io
from pcvr_addon.render import cache


@pytest.fixture
def scene():
    scene = bs.setup(48, 48)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=3.0)
    return scene


@pytest.fixture
def private_tempdir(tmp_path, monkeypatch):
    """Temporary files of the render land here, so a test can see that none are left."""
    directory = tmp_path / "render-temp"
    directory.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(directory))
    return directory


def test_sequence_renders_the_frames_file(scene, tmp_path):
    densities = {1: 1.0, 2: 3.0, 3: 2.0}
    for frame, density in densities.items():
        bs.write_vdb(tmp_path / f"smoke_{frame:04d}.vdb", bs.box(density=density))
    obj = bs.add_volume("Smoke", tmp_path / "smoke_0001.vdb")
    obj.data.is_sequence = True
    obj.data.frame_start, obj.data.frame_duration = 1, 3

    scene.frame_set(2)
    image = bs.xray(bs.render(scene))
    bs.assert_matches(image, bs.exact(bs.world_grid(obj, tmp_path / "smoke_0002.vdb")))


def test_mesh_to_volume_renders(scene, private_tempdir):
    bs.add_mesh_to_volume((0.5, 0.5, 0.0), density=2.0)

    image = bs.xray(bs.render(scene))
    # 48 px over 3 units: the cube covers x, y in [0, 1], pixels 24..40 across, rows 8..24 down.
    assert image[12:20, 28:36].min() > 1.0  # density 2 through a unit of depth, give or take the edge
    assert not image[30:, :20].any()
    assert not os.listdir(private_tempdir), "the exported grids were not removed"


def test_geometry_nodes_volume_renders(scene, private_tempdir):
    tree = bpy.data.node_groups.new("Volume Cube", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    cube = tree.nodes.new("GeometryNodeVolumeCube")
    cube.inputs["Min"].default_value = (-0.5, -0.5, -0.5)
    cube.inputs["Max"].default_value = (0.5, 0.5, 0.5)
    tree.links.new(cube.outputs["Volume"], tree.nodes.new("NodeGroupOutput").inputs[0])
    obj = bpy.data.objects.new("Generator", bpy.data.meshes.new("Generator"))
    obj.location = (-0.75, 0.0, 0.0)
    obj.modifiers.new("Nodes", 'NODES').node_group = tree
    scene.collection.objects.link(obj)

    image = bs.xray(bs.render(scene))
    assert image[24, 12] > 0.5  # the cube's centre, x = -0.75
    assert not image[:, 36:].any()
    assert not os.listdir(private_tempdir)


def test_collection_instances(scene, tmp_path, rng):
    filepath = bs.write_vdb(tmp_path / "blob.vdb", bs.blob(rng))
    collection = bpy.data.collections.new("Cloud")
    obj = bs.add_volume("Cloud", filepath, rotation=(0.3, 0.0, 0.0), collection=collection)
    instancer = bpy.data.objects.new("Instancer", None)
    instancer.instance_type = 'COLLECTION'
    instancer.instance_collection = collection
    instancer.location, instancer.scale = (0.6, -0.4, 0.0), (0.8, 0.8, 0.8)
    scene.collection.objects.link(instancer)  # the collection itself is not in the scene

    image = bs.xray(bs.render(scene))
    placed = bs.world_grid(obj, matrix_world=instancer.matrix_world @ obj.matrix_world)
    bs.assert_matches(image, bs.exact(placed))
    assert cache.grids.stats.reads == 1


def test_hidden_and_out_of_view_objects_are_not_read(scene, tmp_path):
    filepath = bs.write_vdb(tmp_path / "box.vdb", bs.box())
    bs.add_volume("Hidden", filepath).hide_render = True
    bs.add_volume("Behind", filepath, location=(0.0, 0.0, 8.0))
    bs.add_volume("Aside", filepath, location=(3.0, 0.0, 0.0))

    assert not bs.xray(bs.render(scene)).any()
    assert cache.grids.stats.reads == 0


def test_rerendering_reads_nothing(scene, tmp_path):
    obj = bs.add_volume("Still", bs.write_vdb(tmp_path / "box.vdb", bs.box()))
    first = bs.xray(bs.render(scene))
    assert cache.grids.stats.reads == 1

    np.testing.assert_array_equal(bs.xray(bs.render(scene)), first)
    scene.frame_set(scene.frame_current + 1)
    obj.location.x = 0.2  # a moved object needs no new read either
    assert bs.xray(bs.render(scene)).any()
    assert cache.grids.stats.reads == 1
    assert cache.grids.stats.hits == 2


def test_changed_file_is_read_again(scene, tmp_path):
    filepath = bs.write_vdb(tmp_path / "box.vdb", bs.box())
    bs.add_volume("Box", filepath)
    first = bs.xray(bs.render(scene))
    bs.write_vdb(filepath, bs.box(density=2.0))
    # Make sure the modification time differs even on a coarse clock.
    os.utime(filepath, ns=(os.stat(filepath).st_atime_ns, os.stat(filepath).st_mtime_ns + 10**9))
    np.testing.assert_allclose(bs.xray(bs.render(scene)), 2 * first, rtol=1e-5)
    assert cache.grids.stats.reads == 2


def test_compositor_uses_the_xray_pass(scene, tmp_path):
    bs.add_volume("Box", bs.write_vdb(tmp_path / "box.vdb", bs.box()))
    tree, output, math_node = bs.compositor(scene)
    layers = tree.nodes.new("CompositorNodeRLayers")
    double = tree.nodes.new(math_node)
    double.operation, double.inputs[1].default_value = 'MULTIPLY', 2.0
    tree.links.new(layers.outputs["XRay"], double.inputs[0])
    tree.links.new(double.outputs[0], output)

    settings = scene.render.image_settings
    settings.file_format, settings.color_depth = 'OPEN_EXR', '32'
    scene.render.filepath = str(tmp_path / "composite.exr")
    bpy.ops.render.render(write_still=True)

    saved = image_io.read_passes(str(tmp_path / "composite.exr"))[""]
    xray = bs.xray(image_io.render_result_passes(scene))
    assert xray.max() > 0
    for channel in range(3):
        np.testing.assert_allclose(saved[:, :, channel], 2 * xray, rtol=1e-6, atol=1e-7)
