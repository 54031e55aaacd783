"""The multiple-scattering tests' cloud: tools/cumulus.py's procedural cumulus as a Grid, and a white cloud's
material as a transfer function."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import pcvr_native as pn

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from tools import cumulus as cumulus_tool  # noqa: E402


def cumulus(n: int = 32, size: float = 2.0, seed: int = 7) -> pn.Grid:
    """The cumulus as a Grid `size` world units wide, centred on the origin."""
    return pn.Grid.from_dense(cumulus_tool.cumulus_values(n, seed), cumulus_tool.index_to_world(n, size))

def white_cloud_tf(density: float, albedo: float = 0.98) -> pn.TransferFunction:
    """A Principled Volume of colour `albedo` and `density` (extinction per world unit at value 1) as a transfer
    function: opacity per world unit 1 - exp(-density) at value 1, linear in the value's extinction."""
    values = np.linspace(0, 1, 33)
    opacity = 1 - np.exp(-density * values)
    return pn.TransferFunction(density=values, rgba=[[albedo] * 3 + [a] for a in opacity], unit_distance=1.0)
