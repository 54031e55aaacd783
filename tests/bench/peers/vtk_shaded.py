"""VTK's fixed-point ray caster as a shaded renderer: one child process per volume, run by
peers/__init__.py with the job's ``scene`` (shaded.py: transfer function, sun, ambient, material).

    python vtk_shaded.py JOB.json      # writes RESULT.json and one premultiplied RGBA .npy per render

The set-up a VTK user writes for the scene PCVR renders, term by term:

| PCVR                                         | VTK                                                              |
|----------------------------------------------|------------------------------------------------------------------|
| TransferFunction colour and opacity points   | vtkColorTransferFunction (RGB space) and the scalar opacity       |
|                                              | vtkPiecewiseFunction at the same points, both linear in between   |
| opacity of a slab `unit_distance` thick      | ScalarOpacityUnitDistance = unit_distance (VTK corrects each      |
|                                              | sample as 1 - (1 - a)^(step / unit), as PCVR does)                |
| Shading(ambient, diffuse, specular, shininess)| the volume property's Ambient, Diffuse, Specular, SpecularPower  |
| sun: direction, colour, strength             | a directional scene light: focal point - position = direction,   |
|                                              | diffuse and specular colour = colour, intensity = strength        |
| ambient colour A (ka * A * c)                | the light's ambient colour A / strength: VTK adds                 |
|                                              | Ambient * intensity * light ambient colour * c, and its lights'   |
|                                              | ambient colour is black by default, which drops the term          |
| two-sided Blinn-Phong                        | the renderer's TwoSidedLighting (on by default)                   |

The mapper runs at full quality (vtk_xray.fixed_point_mapper: AutoAdjustSampleDistances off, one ray
per pixel, the job's sample distance in voxels), and once as it comes ("defaults": sample distances
adapted to a desired frame rate), to show what those defaults trade for speed. Models still differ: VTK reconstructs trilinearly (PCVR
with its Gaussian kernel), takes gradients by central differences on the voxel grid, quantises them
to its encoded normals and reads an 8-bit framebuffer. The image is the framebuffer over a black,
transparent background: premultiplied RGBA as PCVR returns it.
"""

import json
import sys
import time
from pathlib import Path

import numpy as np

from vtk_xray import fixed_point_mapper, read_pixels, read_volume, render_views  # sets VTK's offscreen window first

import vtk  # noqa: E402


def log(msg):
    print(f"[vtk {time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def shaded_volume(config, img, voxel, scene):
    tf, shading = scene["transfer_function"], scene["shading"]
    prop = vtk.vtkVolumeProperty()
    prop.SetInterpolationTypeToLinear()
    prop.ShadeOn()
    prop.SetAmbient(shading["ambient"])
    prop.SetDiffuse(shading["diffuse"])
    prop.SetSpecular(shading["specular"])
    prop.SetSpecularPower(shading["shininess"])
    colour = vtk.vtkColorTransferFunction()
    colour.SetColorSpaceToRGB()
    opacity = vtk.vtkPiecewiseFunction()
    for density, (r, g, b, a) in zip(tf["density"], tf["rgba"]):
        colour.AddRGBPoint(density, r, g, b)
        opacity.AddPoint(density, a)
    prop.SetColor(colour)
    prop.SetScalarOpacity(opacity)
    prop.SetScalarOpacityUnitDistance(tf["unit_distance"])
    mapper = vtk.vtkFixedPointVolumeRayCastMapper() if config.get("defaults") else fixed_point_mapper(config["step"] * voxel)
    mapper.SetBlendModeToComposite()
    mapper.SetInputData(img)
    volume = vtk.vtkVolume()
    volume.SetMapper(mapper)
    volume.SetProperty(prop)
    return volume


def sun_light(scene):
    sun = scene["sun"]
    light = vtk.vtkLight()
    light.SetLightTypeToSceneLight()
    light.PositionalOff()
    light.SetFocalPoint(0.0, 0.0, 0.0)
    light.SetPosition(*(-np.asarray(sun["direction"], dtype=np.float64)))
    light.SetDiffuseColor(*sun["color"])
    light.SetSpecularColor(*sun["color"])
    light.SetIntensity(sun["strength"])
    light.SetAmbientColor(*(np.asarray(scene["ambient"], dtype=np.float64) / sun["strength"]))
    return light


def main(job_path):
    job = json.loads(Path(job_path).read_text())
    img, voxel, _ = read_volume(job["vdb"])
    scene = job["scene"]

    def setup(config, renderer):
        renderer.SetBackground(0.0, 0.0, 0.0)
        renderer.SetBackgroundAlpha(0.0)
        renderer.AddVolume(shaded_volume(config, img, voxel, scene))
        renderer.AutomaticLightCreationOff()
        renderer.AddLight(sun_light(scene))
        renderer.TwoSidedLightingOn()
        return (lambda window, w, h: read_pixels(window, w, h, rgba=True)), (lambda rgba: (rgba, {}))

    render_views(job, setup, log)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
