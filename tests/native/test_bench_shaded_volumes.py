"""The shaded benchmark's pieces that can go wrong quietly, on small data made here (no network): the VolPack
volume's reader (tests/bench/shaded_volumes.py), the re-indexing that lets VTK place a scan converted into
LPS (tests/bench/peers/image_axes.py), the 30 degree perspective (views.py) and the slicing-rings measure
(slicing_rings.py)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench"
sys.path.append(str(BENCH))
sys.path.append(str(BENCH / "peers"))
import shaded_volumes  # noqa: E402
import slicing_rings  # noqa: E402
import views  # noqa: E402
from image_axes import axis_aligned  # noqa: E402


def den_bytes(values_zyx: np.ndarray, length=None) -> bytes:
    """A VolPack .den file as its denfile.c writes one on a little-endian machine: 9 extent triples."""
    z, y, x = values_zyx.shape
    extents = [0, 0, 0, x - 1, y - 1, z - 1, x, y, z]  # least, largest, length: of the original, extract, map
    shorts = [1] + extents * 3 + [0]  # version first, warps last
    n = values_zyx.size if length is None else length
    return (np.array(shorts, dtype="<i2").tobytes() + np.array([n], dtype="<i4").tobytes()
            + values_zyx.astype(np.uint8).tobytes())


def test_a_den_file_reads_x_fastest_with_cube_voxels(tmp_path):
    zyx = np.arange(2 * 3 * 4, dtype=np.uint8).reshape(2, 3, 4)
    path = tmp_path / "tiny.den"
    path.write_bytes(den_bytes(zyx))
    values, index_to_world = shaded_volumes.read_den(path)
    assert values.shape == (4, 3, 2) and values.dtype == np.float32
    assert values[3, 2, 1] == zyx[1, 2, 3]  # [i, j, k] = [x, y, z]
    assert np.array_equal(np.diag(index_to_world), [2.0, 2.0, 2.0, 1.0])


def test_a_den_file_whose_header_disagrees_names_itself(tmp_path):
    path = tmp_path / "short.den"
    path.write_bytes(den_bytes(np.zeros((2, 3, 4)), length=25))
    with pytest.raises(ValueError, match=r"short\.den: the header says 4 x 3 x 2 voxels"):
        shaded_volumes.read_den(path)
    path.write_bytes(b"\x00\x02" + bytes(70))
    with pytest.raises(ValueError, match=r"short\.den: not a little-endian VolPack"):
        shaded_volumes.read_den(path)


def test_axis_aligned_keeps_every_voxel_at_its_world_point(rng):
    values = rng.random((3, 4, 5))
    # As `pcvr_addon convert` places a NIfTI in LPS: index i along +z, j along -y, k along -x.
    index_to_world = np.array([[0, 0, -1.0, 90], [0, -2.0, 0, 125], [0.5, 0, 0, -71], [0, 0, 0, 1]])
    aligned, xf = axis_aligned(values, index_to_world)
    assert np.all(np.diag(xf)[:3] > 0) and np.count_nonzero(xf[:3, :3]) == 3
    for ijk in np.ndindex(values.shape):
        world = index_to_world @ [*ijk, 1.0]
        new = np.rint(np.linalg.solve(xf, world)[:3]).astype(int)
        assert aligned[tuple(new)] == values[ijk]


def test_axis_aligned_refuses_a_rotation():
    c, s = math.cos(0.3), math.sin(0.3)
    with pytest.raises(ValueError, match="one world axis"):
        axis_aligned(np.zeros((2, 2, 2)), [[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])


def test_perspective_with_a_field_of_view_fits_the_volume_at_that_angle():
    shape, index_to_world = (256, 256, 108), np.diag([0.957, 0.957, 1.5, 1.0])
    view = views.perspective(shape, index_to_world, square=512, fov_degrees=30.0)
    assert 2 * math.degrees(math.atan(view["sensor_width"] / 2 / view["lens"])) == pytest.approx(30.0)
    w2c, proj = views.matrices(view)
    corners = np.array([[x, y, z, 1.0] for x in (0, 255) for y in (0, 255) for z in (0, 107)]) @ index_to_world.T
    clip = corners @ (proj @ w2c).T
    ndc = np.abs(clip[:, :2] / clip[:, 3:4])
    # The volume (grown by the kernel radius) fills the image to its margins of 2 pixels: the corners of the
    # voxel centres fall just inside.
    assert 0.95 < ndc.max() < 1.0 - 2 * views.MARGIN_PIXELS / 512 + 1e-9


def test_the_ring_measure_sees_rings_and_not_smooth_shading():
    side = 201
    y, x = np.mgrid[0:side, 0:side]
    r = np.hypot(x - 100, y - 100)
    reference = np.zeros((side, side, 4))
    reference[r < 90] = [0.5, 0.5, 0.5, 1.0]
    smooth, ringed = reference.copy(), reference.copy()
    smooth[..., :3] += (0.1 * (r / 90) ** 2)[..., None] * (r < 90)[..., None]
    ringed[..., :3] += (0.02 * np.sin(r / 2.0))[..., None] * (r < 90)[..., None]
    assert slicing_rings.ring_profile(smooth, reference)["rms"] < 0.05
    # A sine of amplitude 0.02 has an RMS of 0.02 / sqrt(2): 3.6 steps of 1/255; the fit takes a little.
    assert slicing_rings.ring_profile(ringed, reference)["rms"] == pytest.approx(255 * 0.02 / math.sqrt(2), rel=0.1)
