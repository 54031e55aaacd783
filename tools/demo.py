#!/usr/bin/env python3
"""PCVR demo: X-ray of a CT head phantom by post-convolved splatting, checked against the exact render.

    python tools/demo.py --output out/demo_xray.png [--size 128] [--magnification 4]

Steps: generate the 3-D Shepp-Logan head (pcvr_native.phantoms), write it to <output dir>/phantom.vdb
and read it back, frame it with an orthographic camera at the given magnification along an oblique
direction, render with PCVR (gauss1.4 splats, bilinear post-convolution; median time of 3), render
`regular` for the speed-up and `exact` on every 7th pixel for the error, print the numbers and write
the image (1 - exp(-gain * integral), gain putting the median non-zero pixel at mid-grey).

It also writes <output dir>/ct_head.vdb, the same head in Hounsfield units with a quarter cut away and
turned to open towards a camera above (tools/ct_head.py), which `make demo` renders shaded through the
add-on with the CT Bone preset.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

import pcvr_native as pn  # noqa: E402
from pcvr_native import phantoms  # noqa: E402
from pcvr_native.cameras import look_at, ortho  # noqa: E402

import ct_head  # noqa: E402  (beside this file)

EXACT_STEP = 7


def frame(grid, magnification: float, direction) -> "pn.Camera":
    """Orthographic camera along `direction` showing the whole grid, `magnification` pixels per voxel."""
    xf = np.asarray(grid.index_to_world)
    bbox = np.asarray(grid.index_bbox, dtype=np.float64).reshape(-1)  # (i0, j0, k0), (i1, j1, k1)
    lo, hi = bbox[:3] - 2.0, bbox[3:] + 2.0  # kernel radius
    corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    world = (corners @ xf.T)[:, :3]
    centre = world.mean(axis=0)
    reach = float(np.linalg.norm(world - centre, axis=1).max())
    d = np.asarray(direction, dtype=np.float64)
    d /= np.linalg.norm(d)
    w2c = look_at(centre - 2.0 * reach * d, centre)
    # Pixels per index unit in the least magnified image direction.
    voxel = float(np.linalg.svd(w2c[:2, :3] @ xf[:3, :3], compute_uv=False).min())
    pixel = voxel / magnification
    cam_xy = np.abs((np.c_[world, np.ones(8)] @ w2c.T)[:, :2]).max(axis=0)
    width, height = (int(math.ceil(2.0 * v / pixel)) + 4 for v in cam_xy)
    proj = ortho(-width * pixel / 2, width * pixel / 2, -height * pixel / 2, height * pixel / 2, 0.1 * reach,
                 4.0 * reach)
    return pn.Camera(w2c, proj, width, height)


def timed(fn, repeats: int = 3):
    times, result = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return result, statistics.median(times)


def srgb_decode(v: float) -> float:
    return v / 12.92 if v <= 0.04045 else ((v + 0.055) / 1.055) ** 2.4


def tone_map(integral: np.ndarray) -> np.ndarray:
    """Linear grey values 1 - exp(-gain * integral), the median non-zero pixel at display mid-grey."""
    nonzero = integral[integral > 1e-6 * max(float(integral.max()), 1e-30)]
    median = float(np.median(nonzero)) if nonzero.size else 1.0
    target = srgb_decode(0.5)  # linear value that an sRGB PNG shows as 50% grey
    gain = -math.log(1.0 - target) / median
    return (1.0 - np.exp(-gain * np.maximum(integral, 0.0))).astype(np.float32)


def write_png(path: str, grey: np.ndarray) -> None:
    """Through pcvr_addon.io.image_io when it is there, else Blender's bundled OpenImageIO directly."""
    rgb = np.repeat(grey[:, :, None], 3, axis=2)
    try:
        sys.path.insert(0, REPO)
        from pcvr_addon.io.image_io import write_image
    except Exception:  # the add-on's package imports bpy and its engine; any failure: write directly
        write_image = None
    if write_image is not None:
        write_image(path, rgb)
        return
    import bpy
    bpy.utils.expose_bundled_modules()
    import OpenImageIO as oiio
    encoded = np.where(rgb <= 0.0031308, 12.92 * rgb, 1.055 * np.power(np.clip(rgb, 0, 1), 1 / 2.4) - 0.055)
    out = oiio.ImageOutput.create(path)
    if out is None or not out.open(path, oiio.ImageSpec(rgb.shape[1], rgb.shape[0], 3, "uint8")):
        raise OSError(f"'{path}': {oiio.geterror()}")
    ok = out.write_image(np.clip(encoded, 0.0, 1.0).astype(np.float32))
    if not (out.close() and ok):
        raise OSError(f"'{path}': {out.geterror()}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", default="out/demo_xray.png", help="PNG to write")
    parser.add_argument("--size", type=int, default=128, help="phantom resolution (voxels per side)")
    parser.add_argument("--magnification", type=float, default=4.0, help="pixels per voxel")
    parser.add_argument("--threads", type=int, default=0, help="0 = all cores")
    args = parser.parse_args(argv)

    out_dir = os.path.dirname(os.path.abspath(args.output))
    os.makedirs(out_dir, exist_ok=True)
    vdb_path = os.path.join(out_dir, "phantom.vdb")

    t0 = time.perf_counter()
    phantoms.ct_phantom(args.size).grid().write_vdb(vdb_path, "density")
    grid = pn.read_vdb(vdb_path)
    print(f"phantom: {args.size}^3 CT head, {grid.active_voxel_count} active voxels, written to and read "
          f"back from {os.path.relpath(vdb_path)} in {time.perf_counter() - t0:.2f} s")

    head_path = os.path.join(out_dir, "ct_head.vdb")
    ct_head.grid(args.size, cut_away=True, rotation=ct_head.opened_upwards()).write_vdb(head_path, "density")
    print(f"CT head in Hounsfield units, opened: {os.path.relpath(head_path)}")

    camera = frame(grid, args.magnification, direction=(0.35, -0.25, -1.0))
    print(f"camera: orthographic {camera.width}x{camera.height}, magnification {args.magnification:g}, oblique view")

    stats: dict = {}
    image, t_pcvr = timed(lambda: pn.render_xray(grid, camera, "pcvr", "gauss1.4", "bilinear", 0, args.threads,
                                                stats=stats))
    regular, t_regular = timed(lambda: pn.render_xray(grid, camera, "regular", "gauss1.4", "bilinear", 0,
                                                      args.threads))
    t0 = time.perf_counter()
    exact = np.asarray(pn.render_xray(grid, camera, "exact", "gauss1.4", threads=args.threads,
                                      pixel_step=EXACT_STEP), dtype=np.float64)
    t_exact = time.perf_counter() - t0

    voxels = grid.active_voxel_count
    rms = math.sqrt(float(np.mean(exact ** 2)))

    def rel_rmse(img):
        sub = np.asarray(img, dtype=np.float64)[::EXACT_STEP, ::EXACT_STEP]
        return math.sqrt(float(np.mean((sub - exact) ** 2))) / rms

    print(f"pcvr    (gauss1.4 + bilinear, stride {stats.get('strides')}): {t_pcvr * 1e3:8.1f} ms  "
          f"{voxels / t_pcvr / 1e6:6.1f} M active voxels/s  rel. RMSE vs exact {rel_rmse(image):.2e}")
    print(f"regular (gauss1.4):                         {t_regular * 1e3:8.1f} ms  "
          f"{voxels / t_regular / 1e6:6.1f} M active voxels/s  rel. RMSE vs exact {rel_rmse(regular):.2e}")
    print(f"exact   (every {EXACT_STEP}th pixel):                   {t_exact * 1e3:8.1f} ms")
    print(f"pcvr speed-up over regular splatting: {t_regular / t_pcvr:.2f}x  (median of 3, "
          f"threads={args.threads or os.cpu_count()})")

    write_png(args.output, tone_map(np.asarray(image, dtype=np.float64)))
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
