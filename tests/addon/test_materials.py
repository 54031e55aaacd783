"""Shaded mode with volume.pcvr.source = 'MATERIAL': the object's Principled Volume read into one native grid and
transfer function per grid it names (pcvr_addon/scene/volume_material.py)."""

import math

import bpy
import numpy as np
import pcvr_native as pn
import pytest

import blender_scenes as bs
import lit_scenes as ls
import material_scenes as ms
from pcvr_addon.ui import panels as ui
from pcvr_addon.scene import blackbody

from test_ui import draw, panel_context

# Relative to the image's maximum: the single-precision noise of test_shaded (camera matrices, settings).
TOLERANCE = 1e-5


@pytest.fixture(scope="module")
def fire_vdb(tmp_path_factory):
    return ms.write_multi_grid_vdb(tmp_path_factory.mktemp("fire") / "fire.vdb", ms.fire_grids())


def fire_scene(fire_vdb, material):
    """The fire volume with `material`, seen from above by an orthographic camera, lit by a sun: (scene, object)."""
    scene = ls.shaded_setup(48, 48)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=2.4)
    obj = bs.add_volume("Fire", fire_vdb)
    ms.use_material(obj, material)
    ls.add_light('SUN', rotation=(0.4, 0.3, 0.0), power=math.pi)
    return scene, obj


def cycles_coefficients(colour, density, absorption_colour):
    """Cycles' Principled Volume per unit density: (scattering, absorption) per channel, as its node computes
    them (volume_material.py's docstring)."""
    colour, absorption_colour = np.asarray(colour), np.asarray(absorption_colour)
    scattering = colour * density
    absorption = np.maximum(1 - colour, 0) * np.maximum(1 - np.sqrt(absorption_colour), 0) * density
    return scattering, absorption


def test_a_principled_volume_renders_as_render_shaded_with_its_coefficients(fire_vdb):
    colour, absorption_colour, density, anisotropy = (0.75, 0.5, 0.25), (0.25, 0.5, 0.0), 8.0, 0.3
    material = ms.principled_material(Color=(*colour, 1.0), Density=density, Absorption_Color=(*absorption_colour, 1.0),
                                      Anisotropy=anisotropy)
    scene, obj = fire_scene(fire_vdb, material)
    image = ls.combined(bs.render(scene))
    expected = principled_reference(obj, colour, density, absorption_colour, anisotropy)
    assert expected[..., 3].max() > 0.5
    np.testing.assert_allclose(image, expected, atol=TOLERANCE * expected.max())


def principled_reference(obj, colour, density, absorption_colour, anisotropy, **kw):
    """fire_scene's object with a Principled Volume of these inputs, rendered through pcvr_native as the reader
    should make it: grey extinction (the mean of Cycles' coefficients), the scattered share as the colour, 128
    points over the grid's values, the opacity per voxel (0.1 units), the sun of fire_scene."""
    scattering, absorption = cycles_coefficients(colour, density, absorption_colour)
    k = float(np.mean(scattering + absorption))
    grid = bs.world_grid(obj, grid="density")
    values = np.linspace(0.0, grid.value_range[1], 128)
    rgba = [[*(scattering / (scattering + absorption)), 1 - math.exp(-k * v * 0.1)] for v in values]
    tf = pn.TransferFunction(values, rgba, unit_distance=0.1, emission=np.zeros((128, 3)))
    sun = pn.Light.sun(ls.sun_direction((0.4, 0.3, 0.0)), strength=1.0)
    return pn.render_shaded(grid, bs.reference_camera(), tf, lights=[sun], ambient=(0.0, 0.0, 0.0), method="regular",
                            shading=pn.Shading(model="scatter", anisotropy=anisotropy), **kw)


def test_the_color_attribute_colours_each_voxel(tmp_path):
    """Mantaflow's `color` grid (a vector grid, here red on one half of the smoke and blue on the other) named by
    the Principled Volume's Color Attribute: the same render as pcvr_native's with the grid's components as
    albedo_grids, and each half in its colour."""
    grids = ms.fire_grids()
    n = grids["density"].shape[0]
    colour = np.zeros((n, n, n, 3), dtype=np.float32)
    colour[:n // 2], colour[n // 2:] = (1.0, 0.3, 0.1), (0.1, 0.4, 1.0)
    colour[grids["density"] == 0] = 0.0  # as Mantaflow writes it: no colour without smoke
    path = ms.write_multi_grid_vdb(tmp_path / "coloured.vdb", {"density": grids["density"], "color": colour})
    material = ms.principled_material(Color=(0.8, 0.8, 0.8, 1.0), Density=8.0, Color_Attribute="color")
    scene, obj = fire_scene(path, material)
    assert not ms.prepared().warnings
    image = ls.combined(bs.render(scene))

    matrix = np.array(obj.matrix_world)
    albedo = tuple(g.with_index_to_world(matrix @ g.index_to_world) for g in pn.read_vdb_vector(path, "color"))
    expected = principled_reference(obj, (0.8, 0.8, 0.8), 8.0, (0.0, 0.0, 0.0), 0.0, albedo_grids=albedo)
    np.testing.assert_allclose(image, expected, atol=TOLERANCE * expected.max())
    # The volume spans x from -0.8 to 0.8 (16 voxels of 0.1), image columns 8 to 40 of 48 (2.4 units wide).
    red_half, blue_half = image[24, 14], image[24, 34]
    assert red_half[0] > 3 * red_half[2] and blue_half[2] > 3 * blue_half[0]


def test_quick_fire_glows_orange_where_the_flame_is(fire_vdb):
    scene, obj = fire_scene(fire_vdb, ms.quick_smoke_material('FIRE'))
    assert not ms.prepared().warnings  # Blender's own setups are read whole: no node or grid left out
    image = ls.combined(bs.render(scene))
    obj.data.materials[0] = ms.quick_smoke_material('SMOKE')
    assert not ms.prepared().warnings
    smoke = ls.combined(bs.render(scene))

    glow = image[..., :3] - smoke[..., :3]  # the blackbody emission alone
    centre, edge = glow[24, 24], glow[24, 13]  # the flame's heart; 0.65 units out, where only smoke is
    # Orange: red, then a third as much green, little blue (measured 0.30, 0.093, 0.012 at 3000 K to the rim's cooler).
    assert centre[0] > 0.2 and 2 * centre[1] < centre[0] < 5 * centre[1] and centre[1] > 4 * centre[2]
    assert np.all(np.abs(edge) < 1e-3 * centre[0])
    grey = smoke[24, 13, :3]  # Quick Smoke: grey, lit by single scattering (measured 0.0047: the sun's 3 W/m^2
    assert grey[0] > 0.002 and np.ptp(grey) < 1e-6  # through an isotropic phase function, 1 / 4 pi, and its albedo)


def test_blackbody_emission_follows_cycles_formula():
    """At 2500 K with intensity 1: sigma T^4 times the blackbody colour of luminance 1."""
    from pcvr_addon.scene.volume_material import BLACKBODY_SIGMA, GridMedium
    medium = GridMedium(grid="temperature", kelvin=1000.0, blackbody_intensity=1.0)
    emitted = medium.emission_at([2.5])[0]
    np.testing.assert_allclose(emitted, 5.670373e-8 * 1e-6 / math.pi * 2500.0 ** 4 * blackbody.colour(2500.0))
    assert BLACKBODY_SIGMA == pytest.approx(5.670373e-14 / math.pi)
    # 6500 K is close to white (D65), cooler is red, hotter blue.
    assert np.ptp(blackbody.colour(6500.0)) < 0.08
    assert blackbody.colour(1500.0)[0] > 3 * blackbody.colour(1500.0)[1]


def test_an_unsupported_node_warns_and_renders_the_transfer_function(fire_vdb, capsys):
    material = ms.principled_material()
    tree = material.node_tree
    mix = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(mix.outputs["Shader"], tree.nodes["Material Output"].inputs["Volume"])
    scene, obj = fire_scene(fire_vdb, material)
    ls.set_ramp(obj, tf_range=(0.0, 0.2))
    prepared = ms.prepared()
    assert any("Mix Shader" in w and "Fire" in w and "transfer function" in w for w in prepared.warnings)
    assert [volume.inputs.medium for volume in prepared.volumes] == [None]

    image = ls.combined(bs.render(scene))
    obj.data.pcvr.source = 'TRANSFER_FUNCTION'
    np.testing.assert_array_equal(image, ls.combined(bs.render(scene)))


def test_source_switch_draws_in_shaded_mode(fire_vdb):
    scene, obj = fire_scene(fire_vdb, ms.principled_material())
    context = panel_context(scene, volume=obj.data)
    assert "source" in draw(ui.PCVR_DATA_PT_volume, context)
    scene.pcvr.mode = 'XRAY'
    assert "source" not in draw(ui.PCVR_DATA_PT_volume, context)


def test_absorption_plus_flame_linked_emission_reads_as_two_grids():
    """Volume Absorption + Emission whose Strength is the flame grid (an Attribute node, through a reroute), both
    through Add Shader."""
    material = bpy.data.materials.new("Flame")
    if material.node_tree is None:
        material.use_nodes = True
    tree = material.node_tree
    tree.nodes.clear()
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    add = tree.nodes.new("ShaderNodeAddShader")
    absorption = tree.nodes.new("ShaderNodeVolumeAbsorption")
    absorption.inputs["Color"].default_value = (0.5, 0.75, 1.0, 1.0)
    absorption.inputs["Density"].default_value = 2.0
    emission = tree.nodes.new("ShaderNodeEmission")
    emission.inputs["Color"].default_value = (1.0, 0.5, 0.25, 1.0)
    flame = tree.nodes.new("ShaderNodeAttribute")
    flame.attribute_name = "flame"
    reroute = tree.nodes.new("NodeReroute")  # followed
    tree.links.new(flame.outputs["Fac"], reroute.inputs[0])
    tree.links.new(reroute.outputs[0], emission.inputs["Strength"])
    tree.links.new(absorption.outputs[0], add.inputs[0])
    tree.links.new(emission.outputs[0], add.inputs[1])
    tree.links.new(add.outputs[0], output.inputs["Volume"])

    from pcvr_addon.scene import volume_material
    media = volume_material.read(material)
    assert media.warnings == ()
    dense, glowing = media.grids
    # Absorption (1 - C) D per channel: 1, 0.5, 0; one extinction, their mean; nothing scattered.
    assert dense.grid is None and dense.extinction == pytest.approx(0.5) and dense.albedo == (0.0, 0.0, 0.0)
    assert glowing.grid == "flame" and glowing.emission == pytest.approx((1.0, 0.5, 0.25))
    np.testing.assert_allclose(glowing.emission_at([0.0, 2.0]), [[0, 0, 0], [2.0, 1.0, 0.5]])


def test_a_node_feeding_density_is_named():
    material = ms.principled_material()
    tree = material.node_tree
    math_node = tree.nodes.new("ShaderNodeMath")
    tree.links.new(math_node.outputs[0], tree.nodes["Principled Volume"].inputs["Density"])
    from pcvr_addon.scene import volume_material
    media = volume_material.read(material)
    assert media.grids == () and "node 'Math' (Math) feeding Principled Volume's Density" in media.warnings[0]


def _blackbody_into(material, node_name, socket, temperature):
    """A Blackbody node feeding `socket` of the material's node `node_name`: Temperature a constant, or an
    Attribute node naming a grid."""
    tree = material.node_tree
    node = tree.nodes.new("ShaderNodeBlackbody")
    if isinstance(temperature, str):
        attribute = tree.nodes.new("ShaderNodeAttribute")
        attribute.attribute_type, attribute.attribute_name = 'GEOMETRY', temperature
        tree.links.new(attribute.outputs["Fac"], node.inputs["Temperature"])
    else:
        node.inputs["Temperature"].default_value = temperature
    tree.links.new(node.outputs["Color"], tree.nodes[node_name].inputs[socket])


def test_a_blackbody_node_colours_the_emission():
    from pcvr_addon.scene import volume_material
    # A constant temperature is a constant colour: the Blackbody node's, luminance 1.
    material = ms.principled_material(Density=0.0, Emission_Strength=2.0)
    _blackbody_into(material, "Principled Volume", "Emission Color", 1500.0)
    (medium,) = volume_material.read(material).grids
    np.testing.assert_allclose(medium.constant_emission, 2.0 * blackbody.colour(np.array([1500.0]))[0], rtol=1e-6)
    # A temperature grid: the colour of each value in kelvin, times the strength, on that grid.
    material = ms.principled_material(Density=0.0, Emission_Strength=2.0)
    _blackbody_into(material, "Principled Volume", "Emission Color", "temperature")
    (medium,) = volume_material.read(material).grids
    assert medium.grid == "temperature"
    kelvin = np.array([900.0, 1800.0, 3000.0])
    np.testing.assert_allclose(medium.emission_at(kelvin), 2.0 * blackbody.colour(kelvin), rtol=1e-12)


def test_a_grid_times_a_blackbody_grid_is_named():
    """Strength from the flame grid times the Blackbody colour of the temperature grid: a product of two grids,
    which PCVR (each grid on its own) cannot render; the warning names both."""
    material = ms.principled_material(Density=0.0)
    tree = material.node_tree
    flame = tree.nodes.new("ShaderNodeAttribute")
    flame.attribute_type, flame.attribute_name = 'GEOMETRY', "flame"
    tree.links.new(flame.outputs["Fac"], tree.nodes["Principled Volume"].inputs["Emission Strength"])
    _blackbody_into(material, "Principled Volume", "Emission Color", "temperature")
    from pcvr_addon.scene import volume_material
    media = volume_material.read(material)
    assert media.grids == () and "grid 'flame'" in media.warnings[0] and "grid 'temperature'" in media.warnings[0]
