/// @file block_value_ranges.h
/// @brief Building Grid::block_value_ranges: each block's value ranges over the blocks around it.
#pragma once

#include <vector>

#include "pcvr/grid.h"

namespace pcvr {

/// BlockValueRange of each of `blocks` (active, finite voxels only): its own range, the unions over the
/// 3^3 blocks around it, over the voxels within 12 index units and over the 5^3 blocks, and its bricks'.
/// Uses every thread.
std::vector<BlockValueRange> build_block_value_ranges(const std::vector<VoxelBlock>& blocks);

}  // namespace pcvr
