/// @file compositing.h
/// @brief Front-to-back compositing of premultiplied samples, and the opacity of a sample of given thickness.
///
/// Emission-absorption along a ray, one sample per sheet: a sample of extinction sigma (per world unit)
/// over a ray length l has opacity alpha = 1 - exp(-sigma l) and adds alpha * colour, attenuated by
/// everything in front of it. Front to back, the accumulated (premultiplied) colour C and opacity A
/// become C + (1 - A) alpha colour and A + (1 - A) alpha. Once A passes the renderer's cutoff nothing
/// behind can change the pixel by more than 1 - A, and the pixel stops taking samples (early ray
/// termination; for splatting, the occlusion map turns it into voxels not splatted).
#pragma once

#include <cmath>

namespace pcvr {

struct Rgba {
    float r = 0, g = 0, b = 0, a = 0;
};

/// Opacity of a slab of thickness `length` (world units) of a medium of extinction `extinction`.
inline float slab_opacity(float extinction, float length) { return -std::expm1(-extinction * length); }

/// Adds a sample of (unpremultiplied) colour (r, g, b) and opacity `alpha` behind what `acc` holds.
inline void composite_behind(Rgba& acc, float r, float g, float b, float alpha) {
    const float weight = (1.0f - acc.a) * alpha;
    acc.r += weight * r;
    acc.g += weight * g;
    acc.b += weight * b;
    acc.a += weight;
}

}  // namespace pcvr
