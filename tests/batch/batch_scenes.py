# SPDX-License-Identifier: GPL-3.0-or-later

"""Small volumes for the batch tests: a numbered sequence of blobs that move (every frame the same bounding
box, so that framing one frame frames them all), written with pcvr_native."""

import os

import numpy as np
import pcvr_native as pn

SIZE = 24


def blob(frame, size=SIZE, seed=0):
    """A Gaussian blob that moves along x with `frame`, with some noise, inside a box of active voxels."""
    rng = np.random.default_rng(seed + frame)
    i, j, k = np.meshgrid(*(np.arange(size),) * 3, indexing="ij")
    centre = np.array([size / 3 + frame, size / 2, size / 2])
    values = np.exp(-((i - centre[0]) ** 2 + (j - centre[1]) ** 2 + (k - centre[2]) ** 2) / (size / 5) ** 2)
    values = values + 0.05 * rng.random(values.shape)
    return values.astype(np.float32)


def write_sequence(directory, frames, size=SIZE, name="smoke_{:04d}.vdb"):
    """Files smoke_0001.vdb ... in `directory`, one per frame of `frames`; their paths."""
    os.makedirs(directory, exist_ok=True)
    paths = []
    for frame in frames:
        path = os.path.join(str(directory), name.format(frame))
        pn.Grid.from_dense(blob(frame, size), np.diag([0.1, 0.1, 0.1, 1.0])).write_vdb(path)
        paths.append(path)
    return paths


def write_split_volume(path):
    """Smooth blobs over 160 x 160 x 32 voxels (four 128^3 regions, every voxel active, 3.1 MiB of values): a
    volume that --split cuts into bricks and batches."""
    i, j, k = np.meshgrid(np.arange(160), np.arange(160), np.arange(32), indexing="ij", sparse=True)
    values = 0.05 + sum(np.exp(-((i - ci) ** 2 + (j - cj) ** 2 + (k - ck) ** 2) / (2 * s ** 2))
                        for ci, cj, ck, s in [(50, 60, 14, 20), (110, 100, 18, 25), (80, 30, 16, 10)])
    pn.Grid.from_dense(values.astype(np.float32), np.diag([0.1, 0.1, 0.1, 1.0])).write_vdb(str(path))
    return path
