"""The scenes of materials_bench.py, rendered in Blender by PCVR and by Cycles: a child process with the bpy
module, run as

    python blender_materials.py JOB.json      # writes the job's result (JSON), one .npy and one .png per render

| scene   | what                                                                                              |
|---------|---------------------------------------------------------------------------------------------------|
| ct_bone | tools/ct_head.py's head in Hounsfield units, a quarter cut away, opened towards an orthographic     |
|         | camera above (the command line's scene of a .vdb: a sun of pi W/m^2, Blender's default grey world), |
|         | the CT Bone preset. PCVR renders the preset's Blinn-Phong shading (`pcvr`), and a scattering       |
|         | medium with shadows (`pcvr_scattering`; one octave: `pcvr_scattering_single`, as Cycles' default   |
|         | of 0 volume bounces scatters); Cycles renders a Principled Volume whose colour                      |
|         | is the same ramp over the same range and whose density is the ramp's opacity per voxel as an        |
|         | extinction, -ln(1 - alpha) / voxel size (what pcvr_native makes of it)                              |
| smoke   | tools/smoke_plume.py's plume with Blender's Quick Smoke material (volume.pcvr.source = 'MATERIAL'),  |
| fire    | and with Quick Fire; from the side, a sun from the left, a dark grey world; PCVR with shadows        |
|         | (`pcvr`, as set up by default; one octave: `pcvr_single`; six: `pcvr_six`; ambient occlusion on  |
|         | and off: `pcvr_ao`, `pcvr_no_ao`); Cycles at its default 0 volume bounces                          |
| coloured_smoke | the smoke with a `color` vector grid (orange rising to violet) that its Color Attribute names |
| cloud   | tools/cumulus.py's cumulus (procedural), a Principled Volume of colour 0.98, density 40, anisotropy    |
|         | 0.5, from the side at 160 x 120, a sun of strength 4 from above, a pale blue world (issue 39); PCVR  |
|         | with shadows (`pcvr`: multiple scattering, the default), with one octave (`pcvr_single`), without  |
|         | shadows (`pcvr_no_shadows`); Cycles with 64 volume bounces                                          |
| cloud_point | the cloud lit by a point light instead of the sun                                               |

Each render is timed as a whole (bpy.ops.render.render, reading the file included: PCVR's grid cache is emptied
first); PCVR's time is the least of the job's rounds, Cycles renders once at the job's samples (its default
denoiser) and once at a quarter of them. Images are the Combined pass in linear RGB (.npy) and its sRGB encoding
(the Standard view transform, .png).
"""

import json
import math
import os
import sys
import tempfile
import time

import bpy
import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, REPO)

import pcvr_addon  # noqa: E402
from pcvr_addon.cli import command_scene  # noqa: E402
from pcvr_addon.io import image_io  # noqa: E402
from pcvr_addon.render import cache  # noqa: E402
from pcvr_addon.scene import lighting, transfer_function  # noqa: E402
from pcvr_addon.ui import properties  # noqa: E402
from tools import ct_head, cumulus, smoke_plume  # noqa: E402


def fresh_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if not hasattr(bpy.types.Scene, "pcvr"):
        pcvr_addon.register()
    return bpy.context.scene


def cycles_ramp_material(volume_settings, voxel_size):
    """A Principled Volume that shows `volume_settings`' transfer function as Cycles understands volumes."""
    material = bpy.data.materials.new("CT Bone (Cycles)")
    if material.node_tree is None:  # before 5.0
        material.use_nodes = True
    tree = material.node_tree
    tree.nodes.clear()
    node = tree.nodes.new
    attribute = node("ShaderNodeAttribute")
    attribute.attribute_type, attribute.attribute_name = 'GEOMETRY', "density"
    to_position = node("ShaderNodeMapRange")  # Hounsfield units -> ramp position
    to_position.inputs["From Min"].default_value = volume_settings.tf_min
    to_position.inputs["From Max"].default_value = volume_settings.tf_max
    ramp = node("ShaderNodeValToRGB")
    transfer_function.set_ramp(ramp.color_ramp, transfer_function.ramp_elements(volume_settings.ramp))
    # Opacity of a voxel's thickness -> extinction per unit length: -ln(1 - alpha) / voxel size.
    clear = node("ShaderNodeMath")
    clear.operation, clear.inputs[0].default_value = 'SUBTRACT', 1.0
    log = node("ShaderNodeMath")
    log.operation, log.inputs[1].default_value = 'LOGARITHM', math.e
    extinction = node("ShaderNodeMath")
    extinction.operation, extinction.inputs[1].default_value = 'MULTIPLY', -1.0 / voxel_size
    volume = node("ShaderNodeVolumePrincipled")
    volume.inputs["Density Attribute"].default_value = ""  # the density comes from the ramp alone
    links = tree.links
    links.new(attribute.outputs["Fac"], to_position.inputs["Value"])
    links.new(to_position.outputs["Result"], ramp.inputs["Fac"])
    links.new(ramp.outputs["Color"], volume.inputs["Color"])
    links.new(ramp.outputs["Alpha"], clear.inputs[1])
    links.new(clear.outputs[0], log.inputs[0])
    links.new(log.outputs[0], extinction.inputs[0])
    links.new(extinction.outputs[0], volume.inputs["Density"])
    links.new(volume.outputs[0], node("ShaderNodeOutputMaterial").inputs["Volume"])
    return material


def ct_bone(job, directory):
    """{variant: callable making the scene render it}: the CT head in PCVR's two shadings and in Cycles."""
    head = os.path.join(directory, "ct_head.vdb")
    grid = ct_head.grid(job["ct_size"], cut_away=True, rotation=ct_head.opened_upwards())
    grid.write_vdb(head, "density")
    scene = fresh_scene()
    obj = command_scene.vdb_scene(scene, head, magnification=job["ct_magnification"])
    obj.data.pcvr.apply_preset("CT Bone")
    scene.pcvr.mode = 'SHADED'
    voxel_size = transfer_function.smallest_voxel_spacing(grid.index_to_world)

    def pcvr(shading_model, shadows, **settings):
        def use():
            scene.render.engine = 'PCVR'
            obj.data.pcvr.shading_model, scene.pcvr.shadows = shading_model, shadows
            set_pcvr_settings(obj.data.pcvr, **settings)
        return use

    def cycles():
        if not obj.data.materials:
            obj.data.materials.append(cycles_ramp_material(obj.data.pcvr, voxel_size))
        scene.render.engine = 'CYCLES'

    return scene, int(grid.active_voxel_count), {"pcvr": pcvr('BLINN_PHONG', False),
                                                   "pcvr_scattering": pcvr('SCATTER', True),
                                                   # Cycles' volume bounces stay at the default 0: single scattering
                                                   "pcvr_scattering_single": pcvr('SCATTER', True, octaves=1),
                                                   "pcvr_scattering_six": pcvr('SCATTER', True, octaves=6),
                                                   "pcvr_scattering_ao": pcvr('SCATTER', True, ao=True),
                                                   "pcvr_scattering_no_ao": pcvr('SCATTER', True, ao=False),
                                                   "cycles": cycles}


def set_pcvr_settings(settings, octaves=None, ao=None):
    """A volume's Scattering Octaves and Ambient Occlusion, each None for what a new volume of this model and
    source has (octaves: the property's default; ambient occlusion: on where it scatters, until set)."""
    settings.scattering_octaves = settings.bl_rna.properties["scattering_octaves"].default if octaves is None else octaves
    if ao is None:
        settings.ambient_occlusion, settings.ambient_occlusion_set = properties.scatters(settings), False
    else:
        settings.ambient_occlusion = ao


def side_view_scene(name, vdb_path, pixels, ortho_scale, camera_at):
    """A volume object `name` of the .vdb at `vdb_path`, seen from the side (along +y) by an orthographic camera at
    `camera_at`, `pixels` (width, height), the Standard view transform: (scene, object)."""
    scene = fresh_scene()
    scene.render.resolution_x, scene.render.resolution_y = pixels
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = 'Standard'
    volume = bpy.data.volumes.new(name)
    volume.filepath = vdb_path
    obj = bpy.data.objects.new(name, volume)
    scene.collection.objects.link(obj)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.data.type, camera.data.ortho_scale = 'ORTHO', ortho_scale
    camera.location, camera.rotation_euler = camera_at, (math.pi / 2, 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    return scene, obj


def set_world(scene, colour):
    world = bpy.data.worlds.new("World")
    world.color = colour
    if world.node_tree is not None:
        world.node_tree.nodes["Background"].inputs["Color"].default_value = (*colour, 1.0)
    scene.world = world


def plume_scene(vdb_path, n, size):
    """The plume of `n`^3 voxels seen from the side at `size`^2 pixels, a sun from the left, a dark grey world."""
    extent = n * smoke_plume.VOXEL
    scene, obj = side_view_scene("Plume", vdb_path, (size, size), extent * 1.05, (extent / 2, -10.0, extent / 2))
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
    sun.data.energy, sun.rotation_euler = 3.0, (0.0, 1.0, 0.3)
    scene.collection.objects.link(sun)
    set_world(scene, (0.05, 0.05, 0.05))
    return scene, obj


def plume(style, coloured=False):
    """The plume with Blender's Quick Smoke material of `style`; `coloured`: with a `color` grid, which the
    material's Color Attribute names."""
    def make(job, directory):
        vdb_path = os.path.join(directory, f"plume_{style.lower()}{'_coloured' if coloured else ''}.vdb")
        grids = smoke_plume.plume(job["plume_size"])
        smoke_plume.write_vdb(vdb_path, {**grids, "color": smoke_plume.colour(grids)} if coloured else grids)
        scene, obj = plume_scene(vdb_path, job["plume_size"], job["plume_pixels"])
        material = smoke_plume.quick_material(style)
        if coloured:
            material.node_tree.nodes["Principled Volume"].inputs["Color Attribute"].default_value = "color"
        obj.data.materials.append(material)
        obj.data.pcvr.source = 'MATERIAL'
        scene.pcvr.mode = 'SHADED'
        scene.pcvr.shadows = True

        def engine(name, **settings):
            def use():
                scene.render.engine = name
                set_pcvr_settings(obj.data.pcvr, **settings)
            return use

        # Cycles' volume bounces stay at the default 0 here: it scatters once, as pcvr_single does.
        return scene, int(np.count_nonzero(grids["density"])), {
            "pcvr": engine('PCVR'), "pcvr_single": engine('PCVR', octaves=1), "pcvr_six": engine('PCVR', octaves=6),
            "pcvr_ao": engine('PCVR', ao=True), "pcvr_no_ao": engine('PCVR', ao=False), "cycles": engine('CYCLES')}
    return make


def cloud_material():
    """The issue's dense white cloud: a Principled Volume of colour 0.98, density 40, anisotropy 0.5."""
    material = bpy.data.materials.new("Cloud")
    if material.node_tree is None:  # before 5.0
        material.use_nodes = True
    tree = material.node_tree
    tree.nodes.clear()
    volume = tree.nodes.new("ShaderNodeVolumePrincipled")
    volume.inputs["Color"].default_value = (0.98, 0.98, 0.98, 1.0)
    volume.inputs["Density"].default_value = 40.0
    volume.inputs["Anisotropy"].default_value = 0.5
    tree.links.new(volume.outputs[0], tree.nodes.new("ShaderNodeOutputMaterial").inputs["Volume"])
    return material


def cloud(light):
    """The cumulus lit by a sun or a point light ('SUN', 'POINT'), in PCVR's three ways and in Cycles."""
    def make(job, directory):
        vdb_path = os.path.join(directory, f"cloud_{job['cloud_size']}.vdb")
        if not os.path.exists(vdb_path):
            cumulus.write_vdb(vdb_path, job["cloud_size"])
        scene, obj = side_view_scene("Cloud", vdb_path, job["cloud_pixels"], 1.7, (0.03, -10.0, -0.07))
        obj.data.materials.append(cloud_material())
        obj.data.pcvr.source = 'MATERIAL'
        if light == 'SUN':
            lamp = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
            lamp.data.energy, lamp.rotation_euler = 4.0, (0.6, 0.5, 0.3)
        else:
            lamp = bpy.data.objects.new("Point", bpy.data.lights.new("Point", 'POINT'))
            lamp.data.energy, lamp.location = 1000.0, (-2.0, -2.5, 3.0)
        scene.collection.objects.link(lamp)
        set_world(scene, (0.3, 0.4, 0.6))
        scene.pcvr.mode = 'SHADED'
        scene.cycles.max_bounces = scene.cycles.volume_bounces = 64

        def pcvr(shadows, **settings):
            def use():
                scene.render.engine = 'PCVR'
                scene.pcvr.shadows = shadows
                set_pcvr_settings(obj.data.pcvr, **settings)
            return use

        variants = {"pcvr": pcvr(True), "pcvr_single": pcvr(True, octaves=1), "pcvr_no_shadows": pcvr(False),
                    "pcvr_ao": pcvr(True, ao=True), "pcvr_no_ao": pcvr(True, ao=False),
                    "cycles": lambda: setattr(scene.render, "engine", 'CYCLES')}
        if light != 'SUN':
            del variants["pcvr_no_shadows"]
        return scene, int((cumulus.cumulus_values(job["cloud_size"]) > 0).sum()), variants
    return make


SCENES = {"ct_bone": ct_bone, "smoke": plume('SMOKE'), "fire": plume('FIRE'), "coloured_smoke": plume('SMOKE', True),
          "cloud": cloud('SUN'), "cloud_point": cloud('POINT')}


def timed_render(scene):
    cache.grids.clear()
    start = time.perf_counter()
    bpy.ops.render.render()
    seconds = time.perf_counter() - start
    return image_io.render_result_passes(scene)["ViewLayer.Combined"], seconds


def render_variant(scene, use, samples, rounds):
    """(image, seconds) of one variant: Cycles once at `samples`, PCVR the least time of `rounds`."""
    use()
    if samples:
        scene.cycles.samples = samples
    best = None
    for _ in range(1 if samples else rounds):
        image, seconds = timed_render(scene)
        if best is None or seconds < best[1]:
            best = (image, seconds)
    return best


def cycles_cache_path(job, name, samples, rec):
    """Where a Cycles render is kept between runs (path without extension), or None: only with the job's
    `cycles_cache` folder (PCVR_MATERIALS_CYCLES_CACHE), for iterating on PCVR beside a reference that takes
    minutes; the scene's make-up is not in the key, so empty the folder when a scene changes."""
    if not samples or not job.get("cycles_cache"):
        return None
    return os.path.join(job["cycles_cache"], f"{name}_{samples}spp_{rec['width']}x{rec['height']}")


def render_scene(key, job, directory):
    """One scene's record: each variant's least time over its runs, its image paths; Cycles also at a quarter
    of the samples."""
    scene, voxels, variants = SCENES[key](job, directory)
    rec = {"voxels": voxels, "width": scene.render.resolution_x * scene.render.resolution_percentage // 100,
           "height": scene.render.resolution_y * scene.render.resolution_percentage // 100,
           "world": list(lighting.world_colour(scene.world)), "variants": {}}
    runs = [(variant, None) for variant in variants if variant != "cycles"]
    runs += [("cycles", job["samples"]), ("cycles_quarter", max(1, job["samples"] // 4))]
    for variant, samples in runs:
        name = f"{key}_{variant}"
        npy = os.path.join(job["work_dir"], name + ".npy")
        cached = cycles_cache_path(job, name, samples, rec)
        if cached and os.path.exists(cached + ".json"):
            with open(cached + ".json") as f:
                seconds = json.load(f)["seconds"]
            image = np.load(cached + ".npy")
            print(f"[blender {time.strftime('%H:%M:%S')}] {name}: {seconds:.2f} s, cached", file=sys.stderr, flush=True)
        else:
            image, seconds = render_variant(scene, variants[variant.removesuffix("_quarter")], samples, job["rounds"])
            if cached:
                os.makedirs(os.path.dirname(cached), exist_ok=True)
                np.save(cached + ".npy", np.asarray(image, dtype=np.float32))
                with open(cached + ".json", "w") as f:
                    json.dump({"seconds": seconds}, f)
        np.save(npy, np.asarray(image, dtype=np.float32))
        png = None if variant == "cycles_quarter" else os.path.join(job["image_dir"], name + ".png")  # for scale only
        if png:
            image_io.write_image(png, image)
        rec["variants"][variant] = {"seconds": seconds, "samples": samples, "npy": npy, "png": png}
        print(f"[blender {time.strftime('%H:%M:%S')}] {name}: {seconds:.2f} s", file=sys.stderr, flush=True)
    return rec


def main(job_path):
    with open(job_path) as f:
        job = json.load(f)
    os.makedirs(job["work_dir"], exist_ok=True)
    os.makedirs(job["image_dir"], exist_ok=True)
    result = {"blender": bpy.app.version_string, "scenes": {}}
    try:
        with tempfile.TemporaryDirectory(prefix="pcvr-materials-") as directory:
            for key in job.get("scenes", SCENES):
                result["scenes"][key] = render_scene(key, job, directory)
    finally:
        if hasattr(bpy.types.Scene, "pcvr"):
            pcvr_addon.unregister()
    tmp = job["result"] + ".tmp"
    with open(tmp, "w") as f:
        json.dump(result, f, indent=1)
    os.replace(tmp, job["result"])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
