"""The DRR bench's own geometry (tests/bench/drr_bench.py): the sampled pixels its reference marches, and the
alignment that checks each peer's geometry before it is timed. Neither needs plastimatch or RTK."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.append(str(Path(__file__).resolve().parents[1] / "bench"))
import drr_bench  # noqa: E402


@pytest.mark.parametrize("size, step", [(64, 5), (60, 3), (33, 1)])
def test_sampled_geometry_marches_the_picked_pixels(size, step):
    """The coarse detector's pixel centres are those of every step-th pixel of the full one, for sizes the
    step divides and does not."""
    view = drr_bench.View(size, 30.0, 10.0, (1.0, -2.0, 3.0))
    full = view.geometry()
    coarse, picked = drr_bench.sampled_geometry(full, step)
    assert np.allclose(coarse.pixel_centres(), full.pixel_centres()[picked], atol=1e-9)


def blobs(shape=(48, 56)):
    """A smooth image with no symmetry: two Gaussians of different widths off the centre."""
    r, c = np.mgrid[:shape[0], :shape[1]].astype(np.float64)
    return np.exp(-((r - 20) ** 2 + (c - 31) ** 2) / 30.0) + 0.5 * np.exp(-((r - 30) ** 2 + (c - 17) ** 2) / 12.0)


def test_alignment_of_the_same_image():
    ref = blobs()
    check = drr_bench.alignment(1.02 * ref, ref)
    assert check["flip"] == "none" and max(abs(s) for s in check["shift_px"]) < 0.05
    assert check["scale"] == pytest.approx(1.02, rel=1e-12)
    assert drr_bench.geometry_agrees(check) is None


def test_alignment_finds_a_shift_a_mirror_and_a_scale():
    ref = blobs()
    shifted = drr_bench.alignment(np.roll(ref, (1, -1), axis=(0, 1)), ref)   # one row down, one column left
    assert shifted["flip"] == "none"
    assert shifted["shift_px"] == pytest.approx([-1.0, 1.0], abs=0.1)
    assert shifted["mad_aligned"] < 1e-9 < shifted["mad_as_rendered"]
    assert "shifted" in drr_bench.geometry_agrees(shifted)
    mirrored = drr_bench.alignment(ref[:, ::-1], ref)
    assert mirrored["flip"] == "left-right" and "mirrored" in drr_bench.geometry_agrees(mirrored)
    # plastimatch's cm left in: a tenth of the integral.
    assert "scaled" in drr_bench.geometry_agrees(drr_bench.alignment(ref / 10.0, ref))
