"""Lights and world in pcvr_native's terms: each conversion factor of lighting.py checked against Cycles, which
renders a white diffuse plane lit by the same light; the world colour read from nodes or the viewport colour."""

import math

import bpy
import numpy as np
import pytest

import blender_scenes as bs
import lit_scenes as ls
from pcvr_addon.io import image_io
from pcvr_addon.scene import lighting

HEIGHT = 2.0  # of the lights above the plane


def cycles_plane(light_object):
    """The radiance Cycles renders in the middle of a white diffuse plane (z = 0, facing up) lit by
    `light_object` alone, without a world."""
    scene = bpy.context.scene
    scene.render.engine = 'CYCLES'
    # Without the denoiser (which moves a flat image by 1%) and adaptive sampling.
    scene.cycles.samples = 16
    scene.cycles.use_denoising = scene.cycles.use_adaptive_sampling = False
    scene.render.resolution_x = scene.render.resolution_y = 8
    scene.world = None
    mesh = bpy.data.meshes.new("Plane")
    mesh.from_pydata([(-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0)], [], [(0, 1, 2, 3)])
    material = bpy.data.materials.new("White")
    if material.node_tree is None:  # before 5.0, materials get nodes on request
        material.use_nodes = True
    nodes = material.node_tree.nodes
    nodes.clear()
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (1, 1, 1, 1)
    material.node_tree.links.new(diffuse.outputs[0], nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    mesh.materials.append(material)
    scene.collection.objects.link(bpy.data.objects.new("Plane", mesh))
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=0.05)
    bpy.ops.render.render()
    return image_io.render_result_passes(scene)["ViewLayer.Combined"][..., :3].mean(axis=(0, 1))


def native_irradiance(spec, point=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0)):
    """What pcvr_native's diffuse term (kd 1, white) makes of a LightSpec at `point` facing `normal`."""
    normal = np.asarray(normal)
    if spec.kind == "sun":
        towards = -np.asarray(spec.vector) / np.linalg.norm(spec.vector)
        return np.asarray(spec.color) * spec.strength * max(0.0, towards @ normal)
    offset = np.asarray(spec.vector) - np.asarray(point)
    distance = np.linalg.norm(offset)
    return np.asarray(spec.color) * spec.strength / distance ** 2 * max(0.0, offset / distance @ normal)


LIGHTS = {
    "sun": ('SUN', dict(energy=2.0, angle=0.0), (0.3, 0.2, 0.0)),
    "point": ('POINT', dict(energy=500.0, shadow_soft_size=0.0), (0.0, 0.0, 0.0)),
    "spot": ('SPOT', dict(energy=500.0, shadow_soft_size=0.0, spot_size=2.0), (0.0, 0.0, 0.0)),
    "area": ('AREA', dict(energy=500.0, size=0.05), (0.0, 0.0, 0.0)),
    "area_not_normalised": ('AREA', dict(energy=500.0, size=0.2, normalize=False), (0.0, 0.0, 0.0)),
    "point_not_normalised": ('POINT', dict(energy=50.0, shadow_soft_size=0.0, normalize=False), (0.0, 0.0, 0.0)),
    "point_exposure_temperature": ('POINT', dict(energy=300.0, shadow_soft_size=0.0, exposure=1.5,
                                                 use_temperature=True, temperature=4000.0), (0.0, 0.0, 0.0)),
}


@pytest.mark.parametrize("name", LIGHTS)
def test_light_is_as_bright_as_in_cycles(name):
    kind, settings, rotation = LIGHTS[name]
    settings = dict(settings)
    obj = ls.add_light(kind, location=(0.0, 0.0, HEIGHT), rotation=rotation, power=settings.pop("energy"))
    missing = [key for key in settings if key not in obj.data.bl_rna.properties]
    if missing:  # 4.2 has no exposure, temperature or normalize
        pytest.skip(f"this Blender's lights have no {', '.join(missing)}")
    for key, value in settings.items():
        setattr(obj.data, key, value)
    bpy.context.view_layer.update()
    expected = native_irradiance(lighting.light_spec(obj.data, obj.matrix_world))
    # Cycles' white diffuse plane shows irradiance / pi (Lambert), which is what lighting.py hands pcvr_native
    # as strength. Measured relative differences: 5e-8 (sun), 1.6e-4 (point, spot: the pixels lie up to 0.025
    # away from the point below the light), 4e-4 and 3.5e-3 (area lights 0.05 and 0.2 wide: not points).
    np.testing.assert_allclose(cycles_plane(obj), expected, rtol=0.005)


def test_lights_hidden_from_render_or_dark_are_left_out():
    ls.add_light('SUN', power=1.0)
    ls.add_light('POINT', power=0.0)
    ls.add_light('POINT', power=10.0).hide_render = True
    ls.add_light('POINT', power=10.0, color=(0.0, 0.0, 0.0))
    specs = lighting.scene_lights(bpy.context.evaluated_depsgraph_get())
    assert [spec.kind for spec in specs] == ["sun"]
    assert specs[0].vector == pytest.approx((0.0, 0.0, -1.0)) and specs[0].strength == pytest.approx(1 / math.pi)


def test_world_colour():
    assert lighting.world_colour(None) == (0.0, 0.0, 0.0)
    world = ls.set_world((0.2, 0.3, 0.4))
    assert lighting.world_colour(world) == pytest.approx((0.2, 0.3, 0.4))
    if world.node_tree is not None:  # 5.0: the Background node's colour times its strength
        world.node_tree.nodes["Background"].inputs["Strength"].default_value = 2.0
        assert lighting.world_colour(world) == pytest.approx((0.4, 0.6, 0.8))
