"""Scenes for the material tests: fire-like volumes with several grids in one .vdb file, Blender's Quick Smoke
and Quick Fire materials, and Principled Volume materials set up by hand."""

import bpy
import numpy as np

import blender_scenes as bs
from _io_helpers import file_grids
from tools.smoke_plume import quick_material as quick_smoke_material  # noqa: F401  (the tests use it)

N = 16
VOXEL = 0.1


def fire_grids(n=N):
    """{name: values}: a thin smoke ball (density, up to 0.2: Quick Fire's Density of 5 makes it an extinction of
    1 per unit), a flame in its middle (flame, up to 1) and its temperature (3 at the flame's heart: 3000 K with
    Quick Fire's Temperature of 1000)."""
    i = np.indices((n, n, n), dtype=np.float64) - (n - 1) / 2
    r2 = (i ** 2).sum(axis=0)
    density = np.exp(-r2 / (n / 4) ** 2)
    flame = np.exp(-r2 / (n / 6) ** 2)
    for values in (density, flame):
        values[values < 0.02] = 0.0
    return {"density": (0.2 * density).astype(np.float32), "flame": flame.astype(np.float32),
            "temperature": (3.0 * flame).astype(np.float32)}


def write_multi_grid_vdb(path, grids):
    """A .vdb file holding each of {name: values} (float grids, or vector grids where values are (n, n, n, 3):
    Mantaflow's `color`), centred like bs.centred."""
    import pcvr_native as pn

    pn.write_vdb(path, file_grids(grids, bs.centred(VOXEL, next(iter(grids.values())).shape[0])))
    return str(path)


def principled_material(name="Medium", **inputs):
    """A material whose Principled Volume (with `inputs` by socket name, e.g. Color=(...)) feeds the output."""
    material = bpy.data.materials.new(name)
    if material.node_tree is None:  # Blender before 5.0 makes materials without nodes
        material.use_nodes = True
    tree = material.node_tree
    tree.nodes.clear()
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    node = tree.nodes.new("ShaderNodeVolumePrincipled")
    tree.links.new(node.outputs["Volume"], output.inputs["Volume"])
    for socket, value in inputs.items():
        node.inputs[socket.replace("_", " ")].default_value = value
    return material


def use_material(obj, material):
    obj.data.materials.append(material)
    obj.data.pcvr.source = 'MATERIAL'


def prepared():
    """The current scene as a render prepares it (its volumes, media and the warnings the render reports)."""
    from pcvr_addon.render import prepared_scene
    from pcvr_addon.scene import scene_inputs
    inputs, _ = scene_inputs.read(bpy.context.evaluated_depsgraph_get(), prepared_scene.export_grid)
    return prepared_scene.prepare(inputs)
