# SPDX-License-Identifier: GPL-3.0-or-later

"""The colour of a black body at a temperature, in scene-linear Rec. 709 RGB, for fire (the Principled Volume's
blackbody emission).

Planck's law integrated against the CIE 1931 2-degree colour matching functions, in the analytic multi-lobe fit of
Wyman, Sloan and Shirley, "Simple Analytic Approximations to the CIE XYZ Color Matching Functions" (JCGT 2(2),
2013), from 380 to 780 nm every 5 nm; XYZ to linear Rec. 709 (sRGB's primaries, D65 white) by the standard
matrix, negative components clipped (deep red and blue-white lie outside the gamut), and the result scaled to
luminance 1, so that brightness comes from the intensity alone (Stefan-Boltzmann, in volume_material.py).
"""

import numpy as np

_WAVELENGTHS_NM = np.arange(380.0, 781.0, 5.0)

# (weight, mean nm, sigma below the mean, sigma above) per lobe: Wyman, Sloan and Shirley's fit.
_LOBES = {
    "x": ((1.056, 599.8, 37.9, 31.0), (0.362, 442.0, 16.0, 26.7), (-0.065, 501.1, 20.4, 26.2)),
    "y": ((0.821, 568.8, 46.9, 40.5), (0.286, 530.9, 16.3, 31.1)),
    "z": ((1.217, 437.0, 11.8, 36.0), (0.681, 459.0, 26.0, 13.8)),
}

_XYZ_TO_REC709 = np.array([[3.2406, -1.5372, -0.4986],
                           [-0.9689, 1.8758, 0.0415],
                           [0.0557, -0.2040, 1.0570]])
_LUMINANCE = np.array([0.2126, 0.7152, 0.0722])

_H, _C, _K = 6.62607015e-34, 2.99792458e8, 1.380649e-23  # Planck, light speed, Boltzmann (SI)


def _matching(lobes):
    total = np.zeros_like(_WAVELENGTHS_NM)
    for weight, mean, below, above in lobes:
        sigma = np.where(_WAVELENGTHS_NM < mean, below, above)
        total += weight * np.exp(-0.5 * ((_WAVELENGTHS_NM - mean) / sigma) ** 2)
    return total


_MATCHING = np.stack([_matching(_LOBES[axis]) for axis in "xyz"])  # (3, wavelengths)


def colour(kelvin):
    """Rec. 709 linear RGB of luminance 1 for each temperature in `kelvin` (any shape; at most 1e5 K, below 500 K
    the colour of 500 K): shape + (3,)."""
    t = np.clip(np.asarray(kelvin, dtype=np.float64), 500.0, 1e5)
    metres = _WAVELENGTHS_NM * 1e-9
    # Planck's spectral radiance up to a constant factor (the scale is normalised away).
    radiance = 1.0 / (metres ** 5 * np.expm1(_H * _C / (metres * _K * t[..., None])))
    xyz = radiance @ _MATCHING.T
    rgb = np.maximum(xyz @ _XYZ_TO_REC709.T, 0.0)
    return rgb / (rgb @ _LUMINANCE)[..., None]
