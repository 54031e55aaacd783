"""Small scenes for the add-on tests, and the references they are compared with.

Volumes are 16^3 grids written with pn.Grid.from_dense and images at most 96 x 96 pixels, so that the
"exact" reference (analytic footprints, double precision) stays fast. The reference camera is built
straight from Blender as CONTRACT section 1 defines it, independently of the add-on's camera code.
"""

import bpy
import numpy as np
import pcvr_native as pn

from pcvr_addon import compat
from pcvr_addon.io import image_io

N = 16

# The REGULAR method rasterises tabulated footprints in single precision, projecting each kernel
# affinely under perspective; "exact" integrates analytically in double precision per pixel. The
# differences stay below 0.3% of the image maximum; a camera off by half a pixel costs over 10%.
TOLERANCE = 5e-3


def assert_matches(image, reference, tolerance=TOLERANCE):
    assert image.shape == reference.shape
    assert reference.max() > 0, "the reference shows nothing: the test scene is wrong"
    error = np.abs(image - reference).max() / reference.max()
    assert error <= tolerance, f"max error {error:.2e} of the maximum {reference.max():.3g}"


def blob(rng, n=N, density=1.0):
    """A smooth lumpy density in an n^3 grid, zero on a 2-voxel border."""
    i = np.indices((n, n, n), dtype=np.float64) - (n - 1) / 2
    r2 = (i ** 2).sum(axis=0) / (n / 4) ** 2
    values = np.exp(-r2) * (1 + 0.5 * rng.random((n, n, n)))
    values[values < 0.05] = 0.0
    border = np.ones_like(values, dtype=bool)
    border[2:-2, 2:-2, 2:-2] = False
    values[border] = 0.0
    return (density * values).astype(np.float32)


def box(n=N, lo=4, hi=12, density=1.0):
    values = np.zeros((n, n, n), dtype=np.float32)
    values[lo:hi, lo:hi, lo:hi] = density
    return values


def centred(voxel_size=0.1, n=N):
    """Index to object transform that centres an n^3 grid on the origin."""
    m = np.diag([voxel_size, voxel_size, voxel_size, 1.0])
    m[:3, 3] = -voxel_size * (n - 1) / 2
    return m


def write_vdb(path, values, index_to_world=None, name="density"):
    grid = pn.Grid.from_dense(values, centred() if index_to_world is None else index_to_world)
    grid.write_vdb(str(path), name)
    return str(path)


def add_volume(name, filepath, location=(0, 0, 0), rotation=(0, 0, 0), scale=(1, 1, 1), collection=None):
    volume = bpy.data.volumes.new(name)
    volume.filepath = str(filepath)
    obj = bpy.data.objects.new(name, volume)
    obj.location, obj.rotation_euler, obj.scale = location, rotation, scale
    (collection or bpy.context.scene.collection).objects.link(obj)
    return obj


def add_cube(name="Cube", size=1.0, location=(0, 0, 0)):
    """A mesh cube object in the scene."""
    import bmesh

    mesh = bpy.data.meshes.new(name)
    builder = bmesh.new()
    bmesh.ops.create_cube(builder, size=size)
    builder.to_mesh(mesh)
    builder.free()
    cube = bpy.data.objects.new(name, mesh)
    cube.location = location
    bpy.context.scene.collection.objects.link(cube)
    return cube


def add_mesh_to_volume(cube_location=(0.5, 0.5, 0.0), density=2.0):
    """A Volume object whose Mesh to Volume modifier fills a unit mesh cube at `cube_location` with `density`."""
    cube = add_cube(location=cube_location)
    obj = bpy.data.objects.new("CubeVolume", bpy.data.volumes.new("CubeVolume"))
    bpy.context.scene.collection.objects.link(obj)
    modifier = obj.modifiers.new("Mesh to Volume", 'MESH_TO_VOLUME')
    modifier.object = cube
    modifier.density = density
    return obj


def add_camera(location=(0, 0, 5), rotation=(0, 0, 0), ortho_scale=None, lens=None, shift=(0, 0)):
    """A scene camera; orthographic when ortho_scale is given."""
    data = bpy.data.cameras.new("Camera")
    if ortho_scale is not None:
        data.type = 'ORTHO'
        data.ortho_scale = ortho_scale
    if lens is not None:
        data.lens = lens
    data.shift_x, data.shift_y = shift
    data.clip_start, data.clip_end = 0.1, 100.0
    obj = bpy.data.objects.new("Camera", data)
    obj.location, obj.rotation_euler = location, rotation
    scene = bpy.context.scene
    scene.collection.objects.link(obj)
    scene.camera = obj
    return obj


def setup(width=64, height=48, method='REGULAR', xray_pass=True, passband='PAPER'):
    """A scene rendered by PCVR. The paper's passband by default: the tests compare with `exact`, its model
    (the compensated passband is that model sharpened: tests/native/test_xray_passband.py)."""
    scene = bpy.context.scene
    scene.render.engine = 'PCVR'
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.pcvr.method = method
    scene.pcvr.passband = passband
    bpy.context.view_layer.pcvr.use_pass_xray = xray_pass
    return scene


def compositor(scene):
    """A new, empty compositor node tree for `scene`, the input socket its image goes to, and the node type
    of Math there. Blender 5.0 composites with a node group (compat.composite_with) that ends in a
    Group Output and takes the shader Math node; 4.x with scene.node_tree, which ends in a Composite node."""
    if {"compositing_node_group", "compositor_effects"} & set(scene.bl_rna.properties.keys()):
        tree = bpy.data.node_groups.new("Compositing", "CompositorNodeTree")
        tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
        compat.composite_with(scene, tree)
        return tree, tree.nodes.new("NodeGroupOutput").inputs[0], "ShaderNodeMath"
    scene.use_nodes = True
    tree = scene.node_tree
    tree.nodes.clear()
    return tree, tree.nodes.new("CompositorNodeComposite").inputs["Image"], "CompositorNodeMath"


def render(scene=None):
    """Render with Blender and read back every pass: {"ViewLayer.XRay": (H, W, 1), ...}, row 0 on top."""
    scene = scene or bpy.context.scene
    bpy.ops.render.render(write_still=False)
    return image_io.render_result_passes(scene)


def xray(passes, layer="ViewLayer"):
    return passes[f"{layer}.XRay"][:, :, 0]


def reference_camera(scene=None, width=None, height=None):
    """pn.Camera of the scene camera at the render size, as CONTRACT section 1 defines it."""
    scene = scene or bpy.context.scene
    render = scene.render
    width = width or render.resolution_x * render.resolution_percentage // 100
    height = height or render.resolution_y * render.resolution_percentage // 100
    depsgraph = bpy.context.evaluated_depsgraph_get()
    camera = scene.camera.evaluated_get(depsgraph)
    projection = camera.calc_matrix_camera(depsgraph, x=width, y=height,
                                           scale_x=render.pixel_aspect_x, scale_y=render.pixel_aspect_y)
    world_to_camera = np.linalg.inv(np.array(camera.matrix_world.normalized()))
    return pn.Camera(world_to_camera, np.array(projection), width, height)


def world_grid(obj, filepath=None, grid=None, matrix_world=None):
    """The object's grid read straight from its file, placed in the world."""
    grid = pn.read_vdb(str(filepath or bpy.path.abspath(obj.data.filepath)), grid)
    if matrix_world is None:
        matrix_world = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).matrix_world
    matrix = np.array(matrix_world)
    return grid.with_index_to_world(matrix @ grid.index_to_world)


def exact(grids, camera=None, density_scale=1.0):
    return pn.render_xray(grids, camera or reference_camera(), method="exact", density_scale=density_scale)
