/// @file penumbra.h
/// @brief Soft shadows of a sun with a disc (Blender's sun Angle) on its transmittance lattice, in the manner
/// of percentage-closer soft shadows (Fernando 2005).
///
/// A point at depth w along the sun's rays sees the sun's disc, of angular diameter theta, through a cone
/// that an occluder at depth d cuts in a disc of radius (w - d) tan(theta / 2). The lattice's columns are
/// the sun's central rays, so for each texel: (1) the occluders that can cover part of the disc lie within
/// (w - w0) tan(theta / 2) of its column (w0: where the lattice begins); their mean depth d, weighted by the
/// optical depth they add, stands for the occluder (the sweep keeps each column's weighted mean depth); (2)
/// the light that passes the occluders is averaged over the texels within (w - d) tan(theta / 2) of the
/// column on the slice midway between them and the texel, and the texel keeps its own attenuation over the
/// rest of the way (a receiver's self-shadow is not blurred by the columns beside it, which averaging the
/// texel's own slice did: 1.4 times the error of the hard shadow on a thin penumbra). Squares stand for the
/// discs; summed-area tables make each mean a constant-time read. The reference ray caster averages rays to
/// points spread over the disc instead (raycast_reference.cpp), and judges it.
#pragma once

#include <cstdint>

#include "pcvr/render_control.h"

namespace pcvr {

/// A sun's lattice as the penumbra pass sees it: nu x nv columns du apart, nw slices dw apart from w0,
/// texels laid out [v][w][u].
struct SunLattice {
    int nu = 0, nv = 0, nw = 0;
    float du = 1, w0 = 0, dw = 1;
};

/// Softens `transmittance` (texels times `whole`, rounded) in place. `depth`: each texel's optical depth
/// from the lattice's start; `occluder`: the depth-weighted mean w of what made it (its own w where nothing
/// did). `spread`: tan(theta / 2).
void soften_penumbrae(uint16_t* transmittance, const float* depth, const float* occluder, const SunLattice& lattice,
                      float spread, float whole, RenderControl& control);

}  // namespace pcvr
