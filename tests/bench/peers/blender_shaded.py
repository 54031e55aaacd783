"""Cycles and EEVEE as shaded renderers: one child process per volume, run by peers/__init__.py with
the job's ``scene`` (shaded.py: transfer function, sun, ambient, material).

    python blender_shaded.py JOB.json      # writes RESULT.json and one premultiplied RGBA .npy per render

What a Blender user builds for the scene PCVR renders:

| PCVR                                   | Blender                                                          |
|----------------------------------------|------------------------------------------------------------------|
| transfer function colour               | Principled Volume Color = Color Ramp (linear) of the density at   |
|                                        | the transfer function's points                                    |
| transfer function opacity a of a slab  | Density = extinction -ln(1 - a) / unit_distance, a second Color   |
| unit_distance thick                    | Ramp sampled at EXTINCTION_POINTS densities (a is linear between  |
|                                        | the points, the extinction is not); Absorption Color black, so    |
|                                        | extinction = Density and the scattering albedo = Color           |
| sun (direction, colour, strength)      | a Sun lamp along the same direction, angle 0, strength SUN_GAIN x |
|                                        | diffuse x strength (below)                                        |
| ambient colour A, ka                   | a uniform world of ka x A                                         |
| background                             | Film > Transparent: premultiplied RGBA as PCVR returns it        |

The models differ, and only partly agree:

- **Coverage agrees**: both attenuate by the same extinction, so alpha = 1 - transmittance is the same
  quantity (up to reconstruction: Blender interpolates the grid trilinearly, PCVR with its Gaussian).
- **Colour does not**: Blender scatters light in the medium (isotropic phase function, the sun's light
  attenuated on its way in: self-shadowing), PCVR lights each sample by Blinn-Phong with the density
  gradient as normal, unshadowed, as VTK does. SUN_GAIN makes them meet where they can: a dense
  medium of albedo c, lit and seen head-on, sends back c E / (8 pi) by single scattering
  (Chandrasekhar's law, c E mu0 / (4 pi (mu0 + mu)) at mu0 = mu = 1), where Blinn-Phong gives
  kd E c, so the sun's strength is 8 pi kd E. Away from head-on they part (no specular highlight,
  a softer terminator). A uniform world of ka x A stands for PCVR's ambient term (ka A c).

Engines as a user runs them: Cycles with its default bounces and the denoiser, in ray-marching mode
(``volume_biased``, as the X-ray rows) and in its default volume mode (null scattering); EEVEE with
volumetric shadows on (without them the sun lights every froxel alike and the skull renders flat), its
froxel grid fitted to the volume's depth range (blender_xray). Timing and budget as for X-ray
(blender_xray.render_views), with one warm-up render per engine.
"""

import json
import math
import sys
from pathlib import Path

import bpy
import mathutils
import numpy as np
from blender_xray import build_scene, combined_pass, cycles_settings, eevee_settings, log, render_views, volume_material

SUN_GAIN = 8.0 * math.pi
EXTINCTION_POINTS = 32  # a Color Ramp holds at most 32 elements


def ramp(nodes, points):
    """A linear Color Ramp node through (position, rgb) points."""
    node = nodes.new("ShaderNodeValToRGB")
    node.color_ramp.interpolation = 'LINEAR'
    elements = node.color_ramp.elements
    while len(elements) > len(points):
        elements.remove(elements[-1])
    while len(elements) < len(points):
        elements.new(1.0)
    for element, (position, rgb) in zip(elements, sorted(points)):
        element.position = float(position)
        element.color = (*(float(c) for c in rgb), 1.0)
    return node


def extinction_points(tf):
    """(density, extinction per world unit) at EXTINCTION_POINTS densities: every control point, the
    rest spread over the intervals where the opacity is not 0 (where the extinction curves)."""
    density = np.asarray(tf["density"], dtype=np.float64)
    opacity = np.asarray([c[3] for c in tf["rgba"]], dtype=np.float64)
    visible = [(a, b) for a, b, oa, ob in zip(density, density[1:], opacity, opacity[1:]) if oa > 0 or ob > 0]
    extra = EXTINCTION_POINTS - len(density)
    width = sum(b - a for a, b in visible) or 1.0
    xs = set(density.tolist())
    for a, b in visible:
        n = max(1, int(extra * (b - a) / width))
        xs.update(np.linspace(a, b, n + 2)[1:-1].tolist())
    xs = sorted(xs)[:EXTINCTION_POINTS]
    a = np.clip(np.interp(xs, density, opacity), 0.0, 1.0 - 1e-6)
    return list(zip(xs, -np.log1p(-a) / tf["unit_distance"]))


def principled_material(tf):
    mat, volume, density = volume_material("shaded", "ShaderNodeVolumePrincipled")
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    volume.inputs["Absorption Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    colour = ramp(nodes, [(d, rgba[:3]) for d, rgba in zip(tf["density"], tf["rgba"])])
    extinction = ramp(nodes, [(d, (e, e, e)) for d, e in extinction_points(tf)])
    links.new(density, colour.inputs["Fac"])
    links.new(density, extinction.inputs["Fac"])
    links.new(colour.outputs["Color"], volume.inputs["Color"])
    links.new(extinction.outputs["Color"], volume.inputs["Density"])
    return mat


def add_sun(scene, sun, diffuse):
    lamp = bpy.data.lights.new("sun", 'SUN')
    lamp.color = sun["color"]
    lamp.energy = SUN_GAIN * diffuse * sun["strength"]
    lamp.angle = 0.0
    obj = bpy.data.objects.new("sun", lamp)
    obj.rotation_mode = 'QUATERNION'
    obj.rotation_quaternion = mathutils.Vector(sun["direction"]).to_track_quat('-Z', 'Y')  # a sun shines along -Z
    scene.collection.objects.link(obj)


def main(job_path):
    job = json.loads(Path(job_path).read_text())
    sys.path.insert(0, job["repo"])
    sc = job["scene"]
    world = [sc["shading"]["ambient"] * a for a in sc["ambient"]]
    scene = build_scene(job["vdb"], lambda: principled_material(sc["transfer_function"]), world, transparent=True)
    add_sun(scene, sc["sun"], sc["shading"]["diffuse"])

    def configure(config, view):
        if config["engine"] == "CYCLES":
            cycles = cycles_settings(scene, config)
            cycles.use_denoising = config["denoise"]
            cycles.volume_biased = config["ray_marching"]
        else:
            eevee_settings(scene, config, view).use_volumetric_shadows = True

    # One warm-up per engine: a second configuration of the same engine loads no new kernels or shaders.
    render_views(job, scene, configure, lambda scene, config: (combined_pass(scene), {}), log,
                 warm_key=lambda config: config["engine"])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
