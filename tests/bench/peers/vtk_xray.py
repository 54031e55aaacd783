"""VTK's volume mappers as X-ray renderers: one child process per volume, run by peers/__init__.py.

    python vtk_xray.py JOB.json      # writes RESULT.json and one .npy image per render

What a scientific user would pick, offscreen (EGL, Mesa's llvmpipe on this CPU-only machine):

| mapper                               | X-ray set-up                                                    | integral from pixel I |
|--------------------------------------|-----------------------------------------------------------------|-----------------------|
| vtkGPUVolumeRayCastMapper, additive  | constant scalar opacity c: the shader sums c * (step / unit     | I / gain              |
|                                      | distance) * value / max over the samples (values normalised to  |                       |
|                                      | the data range; the minimum is 0 here), clamps to [0, 1]         |                       |
| vtkFixedPointVolumeRayCastMapper     | composite, white colour on black, opacity per unit distance     | -ln(1 - I) / k        |
|                                      | 1 - exp(-k v u) (256-point table): I = 1 - exp(-k * integral)   |                       |

Times are wall-clock seconds of ``Render()`` plus the read-back that waits for it, after one
warm-up render per view; repeated up to 3 times (the job's `repeats`) when cheap (median). The fixed-point mapper runs at
full quality (fixed_point_mapper: VTK's frame-rate adaptation off). Both read back the 8-bit
framebuffer (VTK's render windows are RGBA8): that quantisation is part of what a VTK user gets and
shows in the error. The gain (and k) map the largest exact integral to 0.95 (optical depth 1.0), as a
user would set the transfer function's range to the data.

The volume is the benchmark's .vdb file read by pcvr_native (VTK has no OpenVDB reader in its
wheel) into vtkImageData with the grid's origin and spacing. The camera is the view's: position,
focal point and up from the view matrix, parallel scale or view angle and clip range from the
projection; ``camera_error`` reports how far VTK's composite matrix is from the view's.
"""

import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")

import vtk  # noqa: E402
from vtk.util import numpy_support  # noqa: E402

from budget import Budget  # noqa: E402
from image_axes import axis_aligned  # noqa: E402

OPTICAL_DEPTH = 1.0   # fixed-point mapper: k * largest integral
ADDITIVE_TOP = 0.95   # GPU mapper: largest integral -> this pixel value
TABLE_POINTS = 256


def log(msg):
    print(f"[vtk {time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def image_data(values, index_to_world):
    values, xf = axis_aligned(values, index_to_world)
    lin = xf[:3, :3]
    img = vtk.vtkImageData()
    img.SetDimensions(*values.shape)
    img.SetSpacing(*np.diag(lin))
    img.SetOrigin(*xf[:3, 3])
    flat = np.ascontiguousarray(values, dtype=np.float32).ravel(order="F")  # VTK: x fastest
    img.GetPointData().SetScalars(numpy_support.numpy_to_vtk(flat, deep=True))
    return img


def set_camera(renderer, view, w2c, proj):
    cam = renderer.GetActiveCamera()
    c2w = np.linalg.inv(w2c)
    eye, up, forward = c2w[:3, 3], c2w[:3, 1], -c2w[:3, 2]
    near, far = view["clip_start"], view["clip_end"]
    cam.SetPosition(*eye)
    cam.SetFocalPoint(*(eye + forward * 0.5 * (near + far)))
    cam.SetViewUp(*up)
    cam.SetClippingRange(near, far)
    if view["type"] == "ORTHO":
        cam.ParallelProjectionOn()
        cam.SetParallelScale(1.0 / proj[1, 1])   # half the image height in world units
    else:
        cam.ParallelProjectionOff()
        cam.SetViewAngle(math.degrees(2.0 * math.atan(1.0 / proj[1, 1])))
    aspect = view["width"] / view["height"]
    vtk_proj = cam.GetCompositeProjectionTransformMatrix(aspect, -1.0, 1.0)
    ours = proj @ w2c
    theirs = np.array([[vtk_proj.GetElement(i, j) for j in range(4)] for i in range(4)])
    return float(np.abs(theirs - ours).max() / np.abs(ours).max())


def make_mapper(config, img, vmax, integral_max, voxel):
    prop = vtk.vtkVolumeProperty()
    prop.SetInterpolationTypeToLinear()
    prop.ShadeOff()
    colour = vtk.vtkColorTransferFunction()
    colour.AddRGBPoint(0.0, 1.0, 1.0, 1.0)
    colour.AddRGBPoint(vmax, 1.0, 1.0, 1.0)
    prop.SetColor(colour)
    opacity = vtk.vtkPiecewiseFunction()
    unit = voxel
    prop.SetScalarOpacityUnitDistance(unit)
    step = config["step"] * voxel
    if config["mapper"] == "gpu_additive":
        mapper = vtk.vtkGPUVolumeRayCastMapper()
        mapper.SetBlendModeToAdditive()
        # The shader sums c * (step / unit) * s over the samples, s the value normalised to the data's
        # range, (v - min) / (max - min): with min = 0 that is (c / unit) * integral / max.
        c = ADDITIVE_TOP * unit * vmax / integral_max
        opacity.AddPoint(0.0, c)
        opacity.AddPoint(vmax, c)
        decode = lambda i: np.asarray(i, dtype=np.float64) * unit * vmax / c  # noqa: E731
    else:
        mapper = fixed_point_mapper(step)
        mapper.SetBlendModeToComposite()
        k = OPTICAL_DEPTH / integral_max
        for v in np.linspace(0.0, vmax, TABLE_POINTS):
            opacity.AddPoint(float(v), float(1.0 - math.exp(-k * v * unit)))
        decode = lambda i: -np.log(np.clip(1.0 - np.asarray(i, dtype=np.float64), 1e-6, None)) / k  # noqa: E731
    mapper.SetInputData(img)
    mapper.AutoAdjustSampleDistancesOff()
    mapper.SetSampleDistance(step)
    prop.SetScalarOpacity(opacity)
    volume = vtk.vtkVolume()
    volume.SetMapper(mapper)
    volume.SetProperty(prop)
    return volume, decode


def fixed_point_mapper(step):
    """vtkFixedPointVolumeRayCastMapper at full quality: one ray per pixel and `step` (world units)
    between samples. Its defaults adapt both to a desired frame rate (AutoAdjustSampleDistances: a
    coarser image and sample distance while the frame rate is not met)."""
    mapper = vtk.vtkFixedPointVolumeRayCastMapper()
    mapper.AutoAdjustSampleDistancesOff()
    mapper.SetImageSampleDistance(1.0)
    mapper.SetMinimumImageSampleDistance(1.0)
    mapper.SetMaximumImageSampleDistance(1.0)
    mapper.LockSampleDistanceToInputSpacingOff()
    mapper.SetSampleDistance(step)
    return mapper


def read_pixels(window, width, height, rgba=False):
    """The framebuffer as floats in [0, 1], (height, width, 3 or 4), row 0 on top."""
    grab = vtk.vtkWindowToImageFilter()
    grab.SetInput(window)
    if rgba:
        grab.SetInputBufferTypeToRGBA()
    else:
        grab.SetInputBufferTypeToRGB()
    grab.ReadFrontBufferOff()
    grab.Update()
    pixels = numpy_support.vtk_to_numpy(grab.GetOutput().GetPointData().GetScalars())
    return pixels.reshape(height, width, 4 if rgba else 3)[::-1].astype(np.float64) / 255.0  # VTK's rows start at the bottom


def read_volume(vdb_path):
    """The .vdb file's grid (read by pcvr_native: VTK's wheel has no OpenVDB reader) as vtkImageData
    with the grid's origin and spacing, its voxel size and its values."""
    import pcvr_native as pn
    grid = pn.read_vdb(vdb_path)
    (i0, j0, k0), _ = grid.index_bbox
    values = np.asarray(grid.to_dense())
    xf = np.asarray(grid.index_to_world, dtype=np.float64).copy()
    xf[:3, 3] = xf[:3, :3] @ [i0, j0, k0] + xf[:3, 3]  # the dense array starts at the bbox corner
    return image_data(values, xf), float(abs(np.linalg.det(xf[:3, :3])) ** (1.0 / 3.0)), values


def render_views(job, setup, log):
    """Each configuration on each view that fits the budget: `setup(config, renderer)` adds the volume
    (and lights) to a fresh renderer and returns (read, decode): read(window, width, height) takes the
    framebuffer back (timed: it waits for the render), decode(pixels) gives the image to save and a dict
    of extra record fields. A warm-up render per view pays the context, shaders and the volume's
    upload (and VTK's gradients) first; its time is recorded as warmup_s."""
    out_dir = Path(job["out_dir"])
    out_dir.mkdir(parents=True, exist_ok=True)
    budget = Budget(job["budget_s"])
    results = []
    for config, view_key, view, record in budget.renders(job, results, log):
        w2c = np.linalg.inv(np.asarray(view["matrix_world"], dtype=np.float64))
        proj = np.asarray(job["projections"][view_key], dtype=np.float64)
        renderer = vtk.vtkRenderer()
        read, decode = setup(config, renderer)
        window = vtk.vtkRenderWindow()
        window.SetOffScreenRendering(1)
        window.SetMultiSamples(0)
        window.SetAlphaBitPlanes(1)
        window.AddRenderer(renderer)
        window.SetSize(view["width"], view["height"])
        cam_err = set_camera(renderer, view, w2c, proj)

        cpu = []  # the process's CPU seconds per timed render (VTK's threads and llvmpipe's are in it)

        def timed():
            # Rendering is asynchronous under OpenGL: reading the pixels back waits for it.
            renderer.GetActiveCamera().Modified()
            c0, t0 = time.process_time(), time.perf_counter()
            window.Render()
            pixels = read(window, view["width"], view["height"])
            cpu.append(time.process_time() - c0)
            return time.perf_counter() - t0, pixels

        warmup_s, _ = timed()
        del cpu[:]
        seconds, pixels = budget.repeat(timed, most=job.get("repeats", 3))
        budget.record(config["key"], view, min(seconds))
        path = out_dir / f"{config['key']}_{view_key}.npy"
        image, extra = decode(pixels)
        np.save(path, np.asarray(image, dtype=np.float32))
        renderer_line = next((ln.split(":", 1)[1].strip() for ln in window.ReportCapabilities().splitlines()
                              if ln.startswith("OpenGL renderer string")), "?")
        record.update(seconds=seconds, cpu_seconds=cpu, warmup_s=warmup_s, image=str(path), camera_error=cam_err, **extra,
                      software=f"VTK {vtk.vtkVersion.GetVTKVersion()}, {window.GetClassName()} on {renderer_line}")
        log(f"{config['key']} {view_key}: {np.median(seconds):.2f} s (warm-up {warmup_s:.2f} s), "
            f"camera error {cam_err:.1e}")
        window.Finalize()
        Path(job["result"]).write_text(json.dumps(results))
    Path(job["result"]).write_text(json.dumps(results))


def main(job_path):
    job = json.loads(Path(job_path).read_text())
    img, voxel, values = read_volume(job["vdb"])
    vmax = float(values.max())
    if values.min() > 1e-3 * vmax:  # the additive decode takes the data's minimum as 0 (see make_mapper)
        raise ValueError(f"VTK peer: the volume's minimum {values.min():g} is not near 0 (max {vmax:g})")

    def setup(config, renderer):
        volume, decode = make_mapper(config, img, vmax, job["integral_max"], voxel)
        renderer.SetBackground(0.0, 0.0, 0.0)
        renderer.AddVolume(volume)
        return read_pixels, lambda rgb: (decode(rgb.mean(axis=2)), {"saturated": float((rgb >= 254.5 / 255).mean())})

    render_views(job, setup, log)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
