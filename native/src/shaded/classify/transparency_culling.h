/// @file transparency_culling.h
/// @brief Leaving out the voxels whose every sample the transfer function makes transparent: whole
/// blocks, 4^3 bricks and single voxels, each from the value range of the voxels around it.
#pragma once

#include <cstdint>

#include "pcvr/grid.h"
#include "pcvr/kernel.h"
#include "pcvr/transfer_function.h"
#include "splat/post_convolution.h"

namespace pcvr {

/// How wide a neighbourhood of blocks decides whether a block can be culled as transparent, and how
/// far the post-filter can push a sample beyond its nodes' range.
///
/// Culling block b removes its voxels' contributions from the sheets, from nodes within the kernel
/// radius R of its voxels, and so changes the value or the gradient of samples near it. Every such
/// sample must stay transparent with and without b, so every voxel its value is made of must be in
/// the range the transfer function is tested on: voxels within R + (what the sample's gradient
/// reads) + R + (what its value reads) of b. Across the rays a value reads pixels up to f subgrid
/// nodes away (f = 1 for the bilinear post filter, 2 for the four-tap ones; a node is at most a voxel
/// wide), its gradient one node more: 2 f + 1. Along them, in sheet spacings: a sample on sheet s
/// reads half a spacing, its gradient the sheets either side (1.5); a sample t of the way to s + 1
/// reads sheets s and s + 1 (the clamped cubic stays in their range: max(0.5 + t, 1.5 - t)) and its
/// gradient s - 1 to s + 2 (max(1.5 + t, 2.5 - t)), together 4 - 2 / samples_per_sheet at most. BlockValueRange holds
/// the ranges within 8, 12 and 16 voxels; a single voxel takes a box of the reach itself
/// (Grid::voxel_value_ranges). The post filter's negative lobes let a sample leave the range of its
/// nodes.
struct CullingReach {
    double index_units = 0;  // how far, in index units: 2 R + max(2 f + 1, along)
    int voxels = 0;          // which of BlockValueRange's ranges: within 8, 12 or 16 voxels; 0: cannot cull
    double overshoot = 0;    // of the post filter
};

CullingReach culling_reach(const Kernel& kernel, const PostFilter& filter, bool post_convolved, double spacing_voxels,
                           int samples_per_sheet);

/// What one block splats.
struct BlockCulling {
    bool transparent = false;          ///< nothing: every voxel it has is left out
    int bricks_culled = 0;             ///< its 4^3 bricks left out whole
    int voxels_culled = 0;             ///< active voxels of the other bricks left out one by one
    const VoxelMask* splat = nullptr;  ///< the voxels to splat; null: every active one
};

/// The transparency test of one grid's blocks at one reach: the block's neighbourhood (BlockValueRange),
/// then its bricks', then each voxel's (Grid::voxel_value_ranges, where the grid has them).
class TransparencyCulling {
public:
    /// `single_voxels` false: blocks and bricks only (sampled sheets, sheet_sampling.h, take no voxels).
    TransparencyCulling(const Grid& grid, double density_scale, const CullingReach& reach, const ClassificationTable& table,
                        bool single_voxels = true);

    /// Block `index` of the grid's blocks(). A partial mask is written to `mask`, which `splat` then
    /// points to. Safe to call from several threads.
    BlockCulling cull(size_t index, VoxelMask& mask) const;
    /// Whether single voxels are tested (the grid has voxel ranges at this reach).
    bool per_voxel() const { return voxels_ != nullptr; }

private:
    bool transparent(double lowest, double highest) const;

    const Grid& grid_;
    double density_scale_;
    CullingReach reach_;
    const ClassificationTable& table_;
    const std::vector<BlockValueRange>& ranges_;
    const VoxelValueRanges* voxels_ = nullptr;
    /// Per low level of voxels_, the highest high level whose range is transparent (-1: none).
    std::array<int16_t, 256> transparent_up_to_{};
};

}  // namespace pcvr
