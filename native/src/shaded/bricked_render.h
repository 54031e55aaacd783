/// @file bricked_render.h
/// @brief One brick of a bricked render (a GridStream's shaded or MIP image, bricked_render.cpp).
#pragma once

#include <vector>

#include "pcvr/shaded.h"
#include "view/brick_order.h"

namespace pcvr {

/// Renders `volumes` (one brick's voxels, and the margin's) into `image` (and `depth`) as render_shaded
/// (lighting given) or render_mip would, at level 0, counting only the samples in `owned` (index space of
/// the volumes' grids) and continuing the colour, opacity, depth or maximum already there: bricks so
/// rendered front to back make the whole grid's image.
void render_brick(const std::vector<ShadedVolume>& volumes, const Camera& camera, const Lighting* lighting, const ShadedParams& params,
                  const IndexBox& owned, RenderControl& control, ShadedStats& stats, float* image, float* depth);

}  // namespace pcvr
