#!/usr/bin/env python3
"""Perspective X-ray against orthographic at the same framing: what a perspective voxel costs (issue 37).

Each volume is rendered at m = 0.25 ... 8 pixels per voxel twice: through an orthographic camera, and through a
perspective camera with a narrow field of view, far enough (15 volume widths) that the magnification is nearly
uniform (+-3% over the depth) and equal to the orthographic one at the volume's centre; the same image size.
Renders alternate (orthographic, perspective) and each keeps its least time over the repeats, on one thread.

| volume | what                                                                                  |
|--------|---------------------------------------------------------------------------------------|
| blobs  | 128^3 Gaussian blobs (as tests/bench/ab_builds.py): sparse, smooth                    |
| ct     | the 128^3 Shepp-Logan CT phantom inside a scanner's round field of view (0.05 inside, |
|        | a hard edge): dense, every voxel in the cylinder active, as a real CT through a map    |

    python tests/bench/perspective_bench.py [--repeats 5]              # the module on sys.path
    python tests/bench/perspective_bench.py --builds A B [--rounds 3]  # two builds alternated in one sitting
    python tests/bench/perspective_bench.py --accuracy                 # error against exact, 48^3 (slow)
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time

MAGNIFICATIONS = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0)
VOLUMES = ("blobs", "ct")
DISTANCE = 15.0  # camera distance in volume widths


def volume(name: str, n: int):
    """(values, index_to_world): n^3 voxels, one world unit each, centred on the origin."""
    import numpy as np
    from pcvr_native import phantoms

    centred = phantoms.centred_transform((n, n, n), 1.0)
    if name == "blobs":
        rng = np.random.default_rng(3)
        blobs = [(rng.uniform(n / 2 - 30 * n / 128, n / 2 + 30 * n / 128, 3), rng.uniform(2, 9) * n / 128,
                  rng.uniform(0.2, 1.0)) for _ in range(40)]
        return phantoms.gaussian_blobs(n, blobs).values, centred
    i, j = np.meshgrid(np.arange(n) - (n - 1) / 2, np.arange(n) - (n - 1) / 2, indexing="ij")
    field_of_view = (i * i + j * j <= (0.48 * n) ** 2)[:, :, None]
    return phantoms.ct_phantom(n).values + np.float32(0.05) * field_of_view, centred


def cameras(n: int, magnification: float):
    """(orthographic, perspective) pn.Cameras looking down -z at the volume, the same image size, both with
    `magnification` pixels per voxel at the volume's centre."""
    import numpy as np
    import pcvr_native as pn
    from pcvr_native.cameras import frustum, look_at, ortho

    size = max(8, math.ceil((n + 4) * magnification))
    distance = DISTANCE * n
    w2c = look_at((0.0, 0.0, distance), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    half = size / magnification / 2  # world units
    orthographic = pn.Camera(w2c, ortho(-half, half, -half, half, distance - n, distance + n), size, size)
    near = distance - n
    scale = near / distance  # the half-width at the centre's depth, seen at the near plane
    perspective = pn.Camera(w2c, frustum(-half * scale, half * scale, -half * scale, half * scale, near, distance + n),
                            size, size)
    return orthographic, perspective


def timings(repeats: int) -> dict:
    """In the child: {"volume m": [ortho seconds, perspective seconds]}, least over `repeats` alternated renders."""
    import numpy as np
    import pcvr_native as pn

    out = {}
    for name in VOLUMES:
        values, xf = volume(name, 128)
        grid = pn.Grid.from_dense(values, xf)
        for m in MAGNIFICATIONS:
            cams = cameras(128, m)
            least = [math.inf, math.inf]
            for cam in cams:
                pn.render_xray(grid, cam, threads=1)  # tables and pages warm
            for _ in range(repeats):
                for k, cam in enumerate(cams):
                    start = time.perf_counter()
                    pn.render_xray(grid, cam, threads=1)
                    least[k] = min(least[k], time.perf_counter() - start)
            out[f"{name} {m:g}"] = least
    return out


def accuracy() -> dict:
    """{"volume m": [ortho, perspective] relative RMS error against exact}, on 48^3 versions of the volumes."""
    import numpy as np
    import pcvr_native as pn

    out = {}
    for name in VOLUMES:
        values, xf = volume(name, 48)
        grid = pn.Grid.from_dense(values, xf)
        for m in MAGNIFICATIONS:
            errors = []
            for cam in cameras(48, m):
                img = np.asarray(pn.render_xray(grid, cam, antialias=m >= 1), np.float64)
                ref = np.asarray(pn.render_xray(grid, cam, "exact"), np.float64)
                if m < 1:  # zoomed out the image is the pixels' mean: exact at 8 x 8 sub-pixels, averaged
                    fine = pn.Camera(cam.world_to_camera, cam.projection, cam.width * 8, cam.height * 8)
                    ref = np.asarray(pn.render_xray(grid, fine, "exact"), np.float64)
                    ref = ref.reshape(cam.height, 8, cam.width, 8).mean(axis=(1, 3))
                    img = np.asarray(pn.render_xray(grid, cam), np.float64)
                errors.append(float(np.sqrt(np.mean((img - ref) ** 2) / np.mean(ref ** 2))))
            out[f"{name} {m:g}"] = errors
    return out


def run_child(build: str | None, what: str) -> dict:
    env = dict(os.environ)
    if build:
        env["PYTHONPATH"] = os.path.abspath(build) + os.pathsep + env.get("PYTHONPATH", "")
    code = (f"import json, sys; sys.path.insert(0, {os.path.dirname(os.path.abspath(__file__))!r}); "
            f"import perspective_bench as b; print(json.dumps({what}))")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--builds", nargs="+", default=[None], help="folders holding pcvr_native (unpacked wheels)")
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--accuracy", action="store_true")
    args = parser.parse_args()
    if args.accuracy:
        for build in args.builds:
            print(f"relative RMS error against exact, 48^3 ({build or 'sys.path'}): ortho, perspective")
            for scene, (o, p) in run_child(build, "b.accuracy()").items():
                print(f"  {scene:<10} {o:.3e} {p:.3e}")
        return
    best = [{} for _ in args.builds]
    for round_index in range(args.rounds):
        for b, build in enumerate(args.builds):
            for scene, times in run_child(build, f"b.timings({args.repeats})").items():
                best[b][scene] = [min(t, best[b].get(scene, [math.inf, math.inf])[k]) for k, t in enumerate(times)]
        print(f"round {round_index + 1} of {args.rounds} done", file=sys.stderr)
    print(f"load: {os.getloadavg()[0]:.1f}")
    header = "".join(f" | {'ortho ms':>9} {'persp ms':>9} {'ratio':>6}" for _ in args.builds)
    print(f"{'scene':<10}{header}")
    for scene in best[0]:
        row = "".join(f" | {o * 1e3:9.2f} {p * 1e3:9.2f} {p / o:6.2f}" for o, p in (best[b][scene] for b in range(len(args.builds))))
        print(f"{scene:<10}{row}")


if __name__ == "__main__":
    main()
