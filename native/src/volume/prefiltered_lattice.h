/// @file prefiltered_lattice.h
/// @brief Building Grid::prefiltered_lattice: the grid's voxels on a dense lattice, blurred for trilinear sampling.
#pragma once

#include <array>
#include <vector>

#include "pcvr/grid.h"

namespace pcvr {

/// PrefilteredLattice of `blocks` over the active index box `box` ({min i, j, k, max i, j, k}); uses every thread.
PrefilteredLattice build_prefiltered_lattice(const std::vector<VoxelBlock>& blocks, const std::array<int32_t, 6>& box,
                                             float background, float blur);

}  // namespace pcvr
