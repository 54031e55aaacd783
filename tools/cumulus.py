# SPDX-License-Identifier: GPL-3.0-or-later

"""A procedural cumulus (made here, seeded; no outside data): puffs with soft edges heaped on a flat base, eroded by
smooth noise. The cloud of the multiple-scattering tests (tests/native/cloud_scenes.py) and of the materials bench
beside Cycles (tests/bench/blender_materials.py). Densities in [0, 1], z up (the last index); a material's density
multiplies them.

    python tools/cumulus.py OUT.vdb [N]      # writes an N^3 cloud (default 128), 2 units wide, grid 'density'
"""

import sys

import numpy as np


def smooth_noise(n: int, cells: int, rng) -> np.ndarray:
    """Noise in [-1, 1] on an n^3 lattice: a random (cells + 1)^3 lattice, interpolated trilinearly."""
    coarse = rng.uniform(-1, 1, (cells + 1,) * 3).astype(np.float32)
    at = np.linspace(0, cells, n, dtype=np.float32)
    lower = np.minimum(at.astype(int), cells - 1)
    frac = at - lower
    out = coarse
    for axis in range(3):
        shape = [1, 1, 1]
        shape[axis] = n
        w = frac.reshape(shape)
        out = np.take(out, lower, axis=axis) * (1 - w) + np.take(out, lower + 1, axis=axis) * w
    return out


def cumulus_values(n: int = 32, seed: int = 7) -> np.ndarray:
    """float32 (n, n, n) densities in [0, 1], z up (the last index): a heap of puffs on a flat base."""
    rng = np.random.default_rng(seed)
    x, y, z = (np.mgrid[:n, :n, :n].astype(np.float32) + 0.5) / n
    field = np.full((n, n, n), -1.0, dtype=np.float32)  # 1 - distance over radius: > 0 inside a puff
    # A wide base of puffs, smaller ones heaped on it: the cauliflower of a fair-weather cumulus.
    for count, radius, height in ((6, 0.2, 0.32), (5, 0.16, 0.47), (3, 0.12, 0.62)):
        for _ in range(count):
            cx, cy = rng.uniform(0.32, 0.68, 2)
            cz = height + rng.uniform(-0.04, 0.04)
            d = np.sqrt((x - cx) ** 2 + (y - cy) ** 2 + (z - cz) ** 2) / (radius * rng.uniform(0.85, 1.15))
            field = np.maximum(field, 1 - d)
    field += 0.12 * smooth_noise(n, 8, rng)  # erodes and swells the puffs' edges
    field[z < 0.2] = 0  # the flat base at the condensation level
    return np.clip(field * 5, 0, 1).astype(np.float32)  # 0 outside, 1 a fifth of a puff's radius in


def index_to_world(n: int, size: float = 2.0) -> np.ndarray:
    """Voxels size / n wide, the cloud's box centred on the origin."""
    to_world = np.diag([size / n, size / n, size / n, 1.0])
    to_world[:3, 3] = -size / 2 + size / (2 * n)
    return to_world


def write_vdb(path: str, n: int = 128, size: float = 2.0, seed: int = 7) -> None:
    import pcvr_native as pn

    pn.write_vdb(path, {"density": pn.Grid.from_dense(cumulus_values(n, seed), index_to_world(n, size))})


if __name__ == "__main__":
    write_vdb(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 128)
