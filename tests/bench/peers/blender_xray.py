"""Cycles and EEVEE as X-ray renderers: one child process per volume, run by peers/__init__.py.

    python blender_xray.py JOB.json      # writes RESULT.json and one .npy image per render

The volume is the benchmark's own .vdb file on a Volume object; its material is a Volume Absorption
shader with black colour and density = grid value x k (k per engine, see OPTICAL_DEPTH), so a
pixel's transmittance against a white world is T = exp(-k * integral) and -ln(T) / k is the X-ray
integral. Render settings that would change the pixel values are pinned: Standard view transform
(the render result stays linear either way; this keeps EXR output linear too), a pixel filter 0.01
pixels wide (one point sample at the pixel centre, as PCVR's pixels), no denoising, no adaptive
sampling, float output read back from the render result. Cycles runs in ray-marching mode (``volume_biased``; the default null-scattering
mode is unbiased but far noisier per sample), at the job's samples and step rates, with
``volume_max_steps`` raised so long rays are not cut short.

Times are wall-clock seconds of ``bpy.ops.render.render`` (reading the result back is not
counted), after one warm-up render per configuration (kernel loading, shader compilation and the
volume's upload are paid there once, as in an interactive session); renders that fit the budget are
repeated up to 3 times (median). Views run from the smallest image up, and a render predicted to
exceed the budget is skipped with the reason (peers/budget.py).
"""

import json
import sys
import time
from pathlib import Path

import bpy
import mathutils
import numpy as np
from budget import Budget

MAX_STEPS = 65536
# k * (largest integral): the optical depth of the densest pixel. Cycles: 0.5 keeps T above 0.6, so
# averaging noisy samples of T before -ln (Jensen) barely bends the result; float32 T resolves it
# everywhere. EEVEE stores extinction and integrated transmittance in R11F_G11F_B10F textures (6 or 5
# mantissa bits): on the CT phantom (48^3, m=1, 2 px tiles, 128 slices) optical depths 0.1, 0.5, 1 and 3
# gave 10.2%, 6.8%, 7.2% and 10.9% relative RMSE against exact. Below 0.5 the quantised T dominates,
# above it the froxel integration does; 0.5 is EEVEE's best, so both engines use it.
OPTICAL_DEPTH = {"CYCLES": 0.5, "BLENDER_EEVEE": 0.5, "EEVEE": 0.5}


def log(msg):
    print(f"[blender {time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def volume_material(name, shader):
    """A material whose Volume output is a new `shader` node: (material, that node, the grid's density
    as a socket to feed it)."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    node = nodes.new(shader)
    links.new(node.outputs["Volume"], out.inputs["Volume"])
    attr = nodes.new("ShaderNodeAttribute")
    attr.attribute_type = 'GEOMETRY'
    attr.attribute_name = "density"
    return mat, node, attr.outputs["Fac"]


def absorption_material(k):
    mat, absorb, density = volume_material("xray", "ShaderNodeVolumeAbsorption")
    absorb.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    scale = mat.node_tree.nodes.new("ShaderNodeMath")
    scale.name = "k"
    scale.operation = 'MULTIPLY'
    scale.inputs[1].default_value = k
    mat.node_tree.links.new(density, scale.inputs[0])
    mat.node_tree.links.new(scale.outputs["Value"], absorb.inputs["Density"])
    return mat


def build_scene(vdb_path, material, world_colour, transparent):
    """A fresh scene: the .vdb file on a Volume object with `material()`, a uniform world of
    `world_colour`, a camera, and the settings that would change pixel values pinned (see above)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    world = bpy.data.worlds.new("world")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*world_colour, 1.0)
    bg.inputs["Strength"].default_value = 1.0
    scene.world = world
    volume = bpy.data.volumes.new("volume")
    volume.filepath = vdb_path
    obj = bpy.data.objects.new("volume", volume)
    scene.collection.objects.link(obj)
    volume.materials.append(material())
    cam = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.view_settings.view_transform = 'Standard'
    scene.view_settings.look = 'None'
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.render.film_transparent = transparent
    scene.render.resolution_percentage = 100
    scene.render.use_compositing = False
    scene.render.use_sequencer = False
    scene.render.filter_size = 0.01   # EEVEE's pixel filter
    scene.cycles.pixel_filter_type = 'BOX'
    scene.cycles.filter_width = 0.01
    return scene


def set_view(scene, view):
    cam = scene.camera
    cam.matrix_world = mathutils.Matrix([list(row) for row in view["matrix_world"]])  # from rows
    data = cam.data
    data.sensor_fit = 'AUTO'
    data.shift_x = data.shift_y = 0.0
    data.clip_start, data.clip_end = view["clip_start"], view["clip_end"]
    if view["type"] == "ORTHO":
        data.type = 'ORTHO'
        data.ortho_scale = view["ortho_scale"]
    else:
        data.type = 'PERSP'
        data.sensor_width = view["sensor_width"]
        data.lens = view["lens"]
    scene.render.resolution_x, scene.render.resolution_y = view["width"], view["height"]
    scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1.0
    bpy.context.view_layer.update()


def blender_matrices(scene, view):
    depsgraph = bpy.context.evaluated_depsgraph_get()
    cam = scene.camera.evaluated_get(depsgraph)
    proj = np.array(cam.calc_matrix_camera(depsgraph, x=view["width"], y=view["height"]))
    w2c = np.linalg.inv(np.array(cam.matrix_world))
    return w2c, proj


def configure(scene, config, view, k):
    bpy.data.materials["xray"].node_tree.nodes["k"].inputs[1].default_value = k
    if config["engine"] == "CYCLES":
        c = cycles_settings(scene, config)
        c.use_denoising = False
        c.volume_biased = True
        c.volume_step_rate = config["step_rate"]
        c.volume_max_steps = MAX_STEPS
        c.max_bounces = 0
        c.volume_bounces = 0
        c.transparent_max_bounces = 0
        for mat in bpy.data.materials:
            mat.cycles.volume_step_rate = 1.0
    else:
        eevee_settings(scene, config, view).use_volumetric_shadows = False


def cycles_settings(scene, config):
    """Cycles on the CPU at the configuration's samples, every pixel sampled alike, a fixed seed."""
    scene.render.engine = 'CYCLES'
    c = scene.cycles
    c.device = 'CPU'
    c.samples = config["samples"]
    c.use_adaptive_sampling = False
    c.seed = 0
    return c


def eevee_settings(scene, config, view):
    """EEVEE's render samples and froxel grid (tile size, slices) fitted to the volume's depth range."""
    scene.render.engine = 'BLENDER_EEVEE'
    e = scene.eevee
    e.taa_render_samples = config["samples"]
    e.volumetric_tile_size = config["tile_size"]
    e.volumetric_samples = config["slices"]
    e.volumetric_sample_distribution = 0.0  # slices evenly spaced in depth, as along a ray
    if hasattr(e, "use_volume_custom_range"):
        e.use_volume_custom_range = True
    # The froxel grid spans the clip range; fit it to the volume's depth range.
    e.volumetric_start, e.volumetric_end = view["depth_range"]
    return e


def render_seconds(cpu=None):
    """Wall seconds of one render; its CPU seconds (the process's, render threads included) are
    appended to `cpu` when given."""
    c0, t0 = time.process_time(), time.perf_counter()
    bpy.ops.render.render(write_still=False)
    if cpu is not None:
        cpu.append(time.process_time() - c0)
    return time.perf_counter() - t0


def software(engine):
    """What rendered: Blender's version, and for EEVEE the OpenGL renderer it got (llvmpipe here)."""
    text = f"Blender {bpy.app.version_string}"
    if engine != "CYCLES":
        import gpu
        text += f", OpenGL {gpu.platform.version_get()} on {gpu.platform.renderer_get()}"
    return text


def render_views(job, scene, configure, read, log, warm_key=lambda config: config["key"]):
    """Each configuration on each view that fits the budget: `configure(config, view)` sets the engine
    up, a warm-up render per `warm_key(config)` (kernels, shaders and the volume's upload, once, as in
    an interactive session), then timed renders; `read(scene, config)` gives the image to save and a
    dict of extra record fields."""
    out_dir = Path(job["out_dir"])
    out_dir.mkdir(parents=True, exist_ok=True)
    budget = Budget(job["budget_s"])
    results = []
    warmed = set()
    for config, view_key, view, record in budget.renders(job, results, log):
        set_view(scene, view)
        configure(config, view)
        w2c, proj = blender_matrices(scene, view)
        record["camera_error"] = max(
            float(np.abs(w2c - np.linalg.inv(np.asarray(view["matrix_world"]))).max()),
            float(np.abs(proj - np.asarray(job["projections"][view_key])).max()
                  / np.abs(job["projections"][view_key]).max()))
        if warm_key(config) not in warmed:
            record["warmup_s"] = render_seconds()
            log(f"{config['key']} {view_key}: warm-up {record['warmup_s']:.1f} s")
            warmed.add(warm_key(config))
        cpu = []
        seconds, _ = budget.repeat(lambda: (render_seconds(cpu), None))
        budget.record(config["key"], view, min(seconds))
        image, extra = read(scene, config)
        path = out_dir / f"{config['key']}_{view_key}.npy"
        np.save(path, np.asarray(image, dtype=np.float32))
        record.update(seconds=seconds, cpu_seconds=cpu, image=str(path), software=software(config["engine"]), **extra)
        log(f"{config['key']} {view_key}: {np.median(seconds):.2f} s x{len(seconds)}, "
            f"camera error {record['camera_error']:.1e}")
        Path(job["result"]).write_text(json.dumps(results))
    Path(job["result"]).write_text(json.dumps(results))


def combined_pass(scene):
    """The last render's Combined pass, float RGBA, row 0 on top."""
    from pcvr_addon.io import image_io
    passes = image_io.render_result_passes(scene)
    combined = passes.get("ViewLayer.Combined")
    if combined is None:
        raise RuntimeError(f"render result has no Combined pass (passes: {sorted(passes)})")
    return combined


def main(job_path):
    job = json.loads(Path(job_path).read_text())
    sys.path.insert(0, job["repo"])
    scene = build_scene(job["vdb"], lambda: absorption_material(1.0), (1.0, 1.0, 1.0), transparent=False)

    def k_of(config):
        # Optical depth of the densest pixel: the engine's own choice (see OPTICAL_DEPTH).
        return OPTICAL_DEPTH[config["engine"]] / job["integral_max"]

    def read(scene, config):
        t = combined_pass(scene)[:, :, :3].mean(axis=2).astype(np.float64)  # transmittance
        return -np.log(np.clip(t, 1e-30, None)) / k_of(config), {"min_transmittance": float(t.min())}

    render_views(job, scene, lambda config, view: configure(scene, config, view, k_of(config)), read, log)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
