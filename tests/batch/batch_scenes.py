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
