/// @file bricked_render.h
/// @brief One brick of a bricked render (a GridStream's shaded or MIP image, bricked_render.cpp).
#pragma once

#include <vector>

#include "pcvr/shaded.h"
#include "view/brick_order.h"

namespace pcvr {

/// What sets a brick's render apart from the whole grid's.
struct BrickRender {
    IndexBox owned;             ///< the samples it composites (index space of the volumes' grids)
    /// Whether transparency culling tests voxels one by one (Grid::voxel_value_ranges) as well as blocks and
    /// bricks: as the whole grid does, which has no voxel ranges beyond VoxelValueRanges::kMostBlocks blocks.
    bool voxel_culling = true;
};

/// Renders `volumes` (one brick's voxels, and the margin's) into `image` (and `depth`) as render_shaded
/// (lighting given) or render_mip would, at level 0, counting only the samples `brick` owns and continuing
/// the colour, opacity, depth or maximum already there: bricks so rendered front to back make the whole
/// grid's image.
void render_brick(const std::vector<ShadedVolume>& volumes, const Camera& camera, const Lighting* lighting, const ShadedParams& params,
                  const BrickRender& brick, RenderControl& control, ShadedStats& stats, float* image, float* depth);

}  // namespace pcvr
