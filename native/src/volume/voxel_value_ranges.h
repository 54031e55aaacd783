/// @file voxel_value_ranges.h
/// @brief Building Grid::voxel_value_ranges: each voxel's value range over a box around it.
#pragma once

#include <vector>

#include "pcvr/grid.h"

namespace pcvr {

/// VoxelValueRanges of `blocks` at `radius` (1 to VoxelValueRanges::kMostRadius); uses every thread.
VoxelValueRanges build_voxel_value_ranges(const std::vector<VoxelBlock>& blocks, float background, int radius);

}  // namespace pcvr
