"""A grid's dense values re-indexed for vtkImageData, which has an origin and a spacing per axis but no
direction: a scan converted into LPS millimetres (pcvr_addon convert) may run its index axes along other
world axes, or backwards (a signed permutation), and VTK's mappers would place it wrongly."""

import numpy as np


def axis_aligned(values, index_to_world):
    """(values, index_to_world) of the same voxels at the same world points, index axis a along world axis
    a, increasing. ValueError unless the transform is a signed permutation times positive spacings."""
    xf = np.asarray(index_to_world, dtype=np.float64)
    lin = xf[:3, :3]
    world_axis = np.abs(lin).argmax(axis=0)  # the world axis each index axis runs along
    off_axis = lin.copy()
    off_axis[world_axis, range(3)] = 0.0
    if sorted(world_axis) != [0, 1, 2] or np.abs(off_axis).max() > 1e-9 * np.abs(lin).max():
        raise ValueError(f"index_to_world must map each index axis onto one world axis, not {lin.tolist()}")
    order = np.argsort(world_axis)  # the index axis along world axis 0, 1, 2
    values = np.transpose(values, order)
    lin, origin = lin[:, order], xf[:3, 3].copy()
    for axis in range(3):
        if lin[axis, axis] < 0:  # runs backwards: start from its far end
            origin += lin[:, axis] * (values.shape[axis] - 1)
            lin[:, axis] = -lin[:, axis]
            values = np.flip(values, axis)
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = lin, origin
    return np.ascontiguousarray(values), out
