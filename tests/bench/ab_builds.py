#!/usr/bin/env python3
"""Two builds of pcvr_native timed against each other, alternated in one sitting: the check every native change
owes the X-ray and shaded speeds (the machines are noisy, so only a ratio from the same sitting counts).

Each round runs build A, then build B, each in a fresh interpreter that renders every scene below several times
and keeps its least time; after all rounds each scene's least time per build and the ratio B / A are printed.

| scene            | what                                                                         |
|------------------|------------------------------------------------------------------------------|
| xray ortho m=4   | render_xray, 128^3 Gaussian blobs, orthographic, 4 pixels a voxel, 1 thread  |
| xray persp m=4   | the same through a 30 degree perspective camera                              |
| xray ortho m=0.7 | the same orthographic, zoomed out (levels and supersampling)                 |
| shaded bone      | render_shaded of the 128^3 CT phantom, 512^2, 'pcvr', an opaque bone ramp, 2 threads |
| shaded soft      | the same with a semi-transparent soft-tissue ramp                            |

    python tests/bench/ab_builds.py BUILD_A BUILD_B [--rounds 5]   # BUILD: a folder holding pcvr_native
                                                                    # (an unpacked wheel), or "installed"
"""

import argparse
import json
import os
import subprocess
import sys
import time

SCENES = ("xray ortho m=4", "xray persp m=4", "xray ortho m=0.7", "shaded bone", "shaded soft")


def render_all(repeats):
    """In the child: {scene: least seconds over `repeats` renders}."""
    import numpy as np
    import pcvr_native as pn
    from pcvr_native import phantoms

    rng = np.random.default_rng(3)
    n = 128
    centred = phantoms.centred_transform((n, n, n), 1.0)  # world [-64, 64]^3, one unit a voxel
    blobs = [(rng.uniform(n / 2 - 30, n / 2 + 30, 3), rng.uniform(2, 9), rng.uniform(0.2, 1.0)) for _ in range(40)]
    blob_grid = pn.Grid.from_dense(phantoms.gaussian_blobs(n, blobs).values, centred)
    ct = pn.Grid.from_dense(phantoms.ct_phantom(n).values, centred)
    # The camera at (0, -distance, 0) looking along +y (Blender's front view), image up +z.
    def world_to_camera(distance):
        return np.array([[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, -distance], [0, 0, 0, 1]], float)

    def ortho(size, magnification):
        half, near, far = size / magnification / 2, n, 3.0 * n
        projection = np.array([[1 / half, 0, 0, 0], [0, 1 / half, 0, 0],
                               [0, 0, -2 / (far - near), -(far + near) / (far - near)], [0, 0, 0, 1]], float)
        return pn.Camera(world_to_camera(2.0 * n), projection, size, size)

    def perspective(size, fov_degrees=30.0):
        f, near, far = 1 / np.tan(np.radians(fov_degrees) / 2), 1.0, 8.0 * n
        projection = np.array([[f, 0, 0, 0], [0, f, 0, 0],
                               [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)], [0, 0, -1, 0]], float)
        return pn.Camera(world_to_camera(2.2 * n), projection, size, size)

    bone = pn.TransferFunction(density=[0.0, 0.45, 0.55, 1.0],
                               rgba=[[0, 0, 0, 0], [0, 0, 0, 0], [1, 0.95, 0.85, 1], [1, 1, 1, 1]])
    soft = pn.TransferFunction(density=[0.0, 0.15, 0.3, 0.5, 1.0],
                               rgba=[[0, 0, 0, 0], [0.8, 0.4, 0.3, 0.02], [0.9, 0.6, 0.5, 0.08], [1, 1, 0.9, 0.5],
                                     [1, 1, 1, 0.9]])
    sun = pn.Light.sun(direction=(0.3, 1.0, -0.4))
    renders = {
        "xray ortho m=4": lambda: pn.render_xray(blob_grid, ortho(512, 4.0), threads=1),
        "xray persp m=4": lambda: pn.render_xray(blob_grid, perspective(512), threads=1),
        "xray ortho m=0.7": lambda: pn.render_xray(blob_grid, ortho(90, 0.7), threads=1),
        "shaded bone": lambda: pn.render_shaded(ct, perspective(512), bone, [sun], threads=2),
        "shaded soft": lambda: pn.render_shaded(ct, perspective(512), soft, [sun], threads=2),
    }
    least = {}
    for scene in SCENES:
        renders[scene]()  # tables, caches and pages warm
        times = []
        for _ in range(repeats):
            start = time.perf_counter()
            renders[scene]()
            times.append(time.perf_counter() - start)
        least[scene] = min(times)
    return least


def run_build(build, repeats):
    env = dict(os.environ)
    if build != "installed":
        env["PYTHONPATH"] = os.path.abspath(build) + os.pathsep + env.get("PYTHONPATH", "")
    code = f"import json, sys; sys.path.insert(0, {os.path.dirname(os.path.abspath(__file__))!r}); " \
           f"import ab_builds; print(json.dumps(ab_builds.render_all({repeats})))"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("build_a")
    parser.add_argument("build_b")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    best = {"A": {}, "B": {}}
    for round_index in range(args.rounds):
        for label, build in (("A", args.build_a), ("B", args.build_b)):
            for scene, seconds in run_build(build, args.repeats).items():
                best[label][scene] = min(seconds, best[label].get(scene, float("inf")))
        print(f"round {round_index + 1} of {args.rounds} done", file=sys.stderr)
    print(f"{'scene':<18} {'A ms':>9} {'B ms':>9} {'B / A':>7}")
    for scene in SCENES:
        a, b = best["A"][scene] * 1e3, best["B"][scene] * 1e3
        print(f"{scene:<18} {a:9.1f} {b:9.1f} {b / a:7.3f}")


if __name__ == "__main__":
    main()
