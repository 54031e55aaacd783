# SPDX-License-Identifier: GPL-3.0-or-later

"""Settings as the user typed them, for the places that write them out as text (presets, the renderers'
arguments): Blender keeps float properties in single precision."""

import numpy as np


def as_typed(value):
    """A float setting as typed: the shortest decimal that rounds to the stored single-precision value is what
    the user entered (0.99 rather than 0.9900000095367432)."""
    return float(str(np.float32(value)))
