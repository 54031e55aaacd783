/// @file block_plan.h
/// @brief Which voxel blocks can change the image, and at which subgrid stride each is splatted.
///
/// Culling happens per 8^3 block before any voxel is touched: a block whose projected footprint
/// misses the area the splat grid covers, or that lies wholly outside the clip range, costs nothing.
/// Blocks that straddle a clip plane are marked so their voxels are tested one by one.
/// The stride of a block is the node spacing that does not undersample its projected voxel spacing:
/// with `fractional_strides` the least magnification over its corners itself (on a ladder of bands,
/// see automatic_stride), else its floor. One value for an orthographic view, a few depth bands under
/// perspective (nearer blocks are magnified more and take a coarser subgrid).
#pragma once

#include <cstdint>
#include <limits>
#include <map>
#include <vector>

#include "pcvr/clip_region.h"
#include "pcvr/grid.h"
#include "pcvr/render_control.h"
#include "pcvr/stride.h"
#include "view/view_projection.h"

namespace pcvr {

struct PlannedBlock {
    uint32_t index;         ///< into Grid::blocks()
    bool needs_clip_test;   ///< straddles a clip plane: test each voxel's centre
    bool exact_footprints;  ///< may hold voxels whose linearised footprint is off by more than
                            ///< BlockPlanParams::footprint_tolerance (src/splat/near_eye_splat.h)
    bool cut = false;       ///< its kernels may straddle BlockPlanParams::clip (src/splat/cut_splat.h)
    /// Pixel bounds of everything the block's footprints can touch (the whole plane when unknown).
    float min_x, min_y, max_x, max_y;
};

struct BlockPlanParams {
    double kernel_radius = 2.0;  ///< index units
    int fixed_stride = 0;        ///< > 0: every block uses this stride; 0: automatic per block
    int margin_nodes = 0;        ///< nodes the splat grid extends beyond the image on each side
    /// Bilinear spreading replaces the footprint by a one-node tent, which only reconstructs when the
    /// nodes are about one voxel apart: round the stride to the nearest instead of flooring it.
    bool nearest_stride = false;
    /// Automatic strides need not be whole pixels: a node per projected voxel spacing keeps every
    /// footprint within PCVR's 4 x 4 window at any magnification (X-ray; the sheet renderer's
    /// post-convolution needs whole strides).
    bool fractional_strides = false;
    /// Cull blocks whose voxel centres all lie before the near or beyond the far plane (X-ray clips
    /// per voxel). The shaded renderer clips per sample instead and culls by depth itself.
    bool clip_planes = true;
    /// Perspective views: blocks that may hold voxels whose linearised_footprint_error (src/
    /// near_eye_splat.h) exceeds this are marked exact_footprints, and their bounds left open
    /// (exact footprints reach further than linearised ones). Infinity: none.
    double footprint_tolerance = std::numeric_limits<double>::infinity();
    /// The clip planes and crop box in the grid's index space (pcvr/clip_region.h): blocks whose
    /// kernels lie wholly outside are dropped (BlockPlan::blocks_clipped), those that straddle marked cut.
    const ClipRegion* clip = nullptr;
};

struct BlockPlan {
    /// stride (pixels between subgrid nodes; whole unless fractional_strides) -> blocks splatted at it
    std::map<double, std::vector<PlannedBlock>> by_stride;
    uint64_t blocks_total = 0;
    uint64_t blocks_culled = 0;   ///< outside the view or the camera's clip range
    uint64_t blocks_clipped = 0;  ///< wholly outside BlockPlanParams::clip
    double min_magnification = 0;  ///< over the kept blocks (pixels per voxel)
    double max_magnification = 0;
};

/// `control`, when given, is polled between chunks of blocks (a plan of a million blocks takes a
/// quarter of a second) and stops the plan with Cancelled.
BlockPlan plan_blocks(const std::vector<VoxelBlock>& blocks, const ViewProjection& view, const BlockPlanParams& params,
                      const RenderControl* control = nullptr);

}  // namespace pcvr
