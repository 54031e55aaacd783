/// @file emission.h
/// @brief The light a sample of an emitting medium sends out of the front of its own stretch of ray.
///
/// A stretch of length L with constant extinction sigma and emission e (radiance per world unit of ray)
/// sends the integral of e exp(-sigma x) over x in [0, L] out of its front end: e (1 - exp(-sigma L)) / sigma,
/// and e L where nothing absorbs. Both shaded renderers (the sheet walk and the ray caster) add e times this
/// length, attenuated by what lies in front, beside the reflected light that the opacity carries; so an
/// emitting slab's brightness does not depend on how finely it is sampled.
#pragma once

#include <cmath>

#include "pcvr/lanes.h"

namespace pcvr {

/// The length that multiplies the emission: (1 - exp(-sigma L)) / sigma, L where sigma is 0.
inline double emitted_length(double sigma, double length) {
    const double x = sigma * length;
    return x > 0 ? -std::expm1(-x) / sigma : length;
}

/// The same for eight samples, given their opacity 1 - exp(-sigma L) already. Below sigma L = 0.01 the
/// series L (1 - x / 2 + x^2 / 6) (error under 5e-8): there 1 - exp(-x) in float has lost digits.
inline float8 emitted_length(float8 sigma, float8 length, float8 opacity) {
    const float8 x = sigma * length;
    const int8x thin = x < 0.01f;
    const float8 series = length * (1.0f - x * (0.5f - x * (1.0f / 6.0f)));
    return select8(thin, series, opacity / select8(thin, broadcast8(1.0f), sigma));
}

}  // namespace pcvr
