#include "shaded/classify/transparency_culling.h"

#include <algorithm>
#include <cmath>

namespace pcvr {

CullingReach culling_reach(const Kernel& kernel, const PostFilter& filter, bool post_convolved, double spacing_voxels,
                           int samples_per_sheet) {
    const double f = post_convolved ? filter.reach_nodes() : 0.0;
    const double along = (samples_per_sheet > 1 ? 4.0 - 2.0 / samples_per_sheet : 2.0) * spacing_voxels;
    const double reach = 2.0 * kernel.radius() + std::max(2.0 * f + 1.0, along);
    CullingReach out;
    out.index_units = reach;
    for (int within : {8, 12, 16})
        if (out.voxels == 0 && reach <= within) out.voxels = within;
    out.overshoot = post_convolved ? filter.overshoot() : 0.0;
    return out;
}

namespace {

/// Kernels sum to one up to a ripple of about 0.5% (gauss1.4): value ranges are widened by twice that.
constexpr double kRippleMargin = 0.01;

/// A block whose samples can only take densities the transfer function makes transparent. A sample
/// is the background plus a weighted sum of values less the background, weights adding up to at most
/// one: between the background and the values around the block.
bool transparent(double lowest, double highest, double background, double density_scale, const CullingReach& reach,
                 const ClassificationTable& table) {
    if (!(lowest <= highest)) lowest = highest = background;  // no active voxel: the background alone
    const double lo = std::min(0.0, (lowest - background) * density_scale);
    const double hi = std::max(0.0, (highest - background) * density_scale);
    const double margin = kRippleMargin * std::max(-lo, hi) + reach.overshoot * (hi - lo);
    const double offset = background * density_scale;
    return table.transparent(offset + lo - margin, offset + hi + margin);
}

bool transparent(const BlockValueRange& r, double background, double density_scale, const CullingReach& reach,
                 const ClassificationTable& table) {
    const auto [lowest, highest] = reach.voxels == 8    ? std::pair{r.reach_min, r.reach_max}
                                   : reach.voxels == 12 ? std::pair{r.mid_min, r.mid_max}
                                                        : std::pair{r.wide_min, r.wide_max};
    return transparent(lowest, highest, background, density_scale, reach, table);
}

/// The bricks of a block that is not transparent whose own neighbourhoods are (the same argument at
/// 4^3 voxels): bit h set for each brick to splat (BlockValueRange::Bricks' order).
uint8_t bricks_to_splat(const BlockValueRange& r, double background, double density_scale, const CullingReach& reach,
                        const ClassificationTable& table) {
    const BlockValueRange::Bricks& b = reach.voxels == 8 ? r.brick_reach : reach.voxels == 12 ? r.brick_mid : r.brick_wide;
    uint8_t keep = 0;
    for (int h = 0; h < 8; ++h)
        if (!transparent(b.lo[h], b.hi[h], background, density_scale, reach, table)) keep |= uint8_t(1u << h);
    return keep;
}

/// The voxels of the bricks in `bricks` (bit (i >> 2) << 2 | (j >> 2) << 1 | k >> 2).
VoxelMask brick_voxels(uint8_t bricks) {
    VoxelMask mask{};
    for (int offset = 0; offset < VoxelBlock::kSize; ++offset) {
        const int brick = ((offset >> 8) & 1) << 2 | ((offset >> 5) & 1) << 1 | ((offset >> 2) & 1);
        if ((bricks >> brick) & 1) mask[offset >> 6] |= uint64_t(1) << (offset & 63);
    }
    return mask;
}

int count(const VoxelMask& mask) {
    int n = 0;
    for (uint64_t word : mask) n += __builtin_popcountll(word);
    return n;
}

}  // namespace

TransparencyCulling::TransparencyCulling(const Grid& grid, double density_scale, const CullingReach& reach,
                                         const ClassificationTable& table, bool single_voxels)
    : grid_(grid), density_scale_(density_scale), reach_(reach), table_(table), ranges_(grid.block_value_ranges()) {
    const int radius = int(std::ceil(reach.index_units));
    if (!single_voxels || reach.voxels == 0 || radius > VoxelValueRanges::kMostRadius) return;
    voxels_ = grid.voxel_value_ranges(std::max(radius, 1));
    if (!voxels_) return;
    // Ranges only widen with the high end, so each low level's transparent high levels run from it up.
    for (int lo = 0; lo < 256; ++lo) {
        int16_t up_to = -1;
        for (int step = 128; step > 0; step /= 2)
            if (const int hi = std::max(int(up_to), lo - 1) + step; hi < 256 && transparent(voxels_->value(lo), voxels_->value(hi)))
                up_to = int16_t(hi);
        transparent_up_to_[size_t(lo)] = up_to;
    }
}

bool TransparencyCulling::transparent(double lowest, double highest) const {
    return pcvr::transparent(lowest, highest, grid_.background(), density_scale_, reach_, table_);
}

BlockCulling TransparencyCulling::cull(size_t index, VoxelMask& mask) const {
    BlockCulling out;
    if (reach_.voxels == 0) return out;
    const BlockValueRange& r = ranges_[index];
    const uint8_t bricks = pcvr::transparent(r, grid_.background(), density_scale_, reach_, table_)
                               ? 0
                               : bricks_to_splat(r, grid_.background(), density_scale_, reach_, table_);
    if (bricks == 0) {
        out.transparent = true;
        return out;
    }
    out.bricks_culled = 8 - __builtin_popcount(bricks);
    const VoxelBlock& block = grid_.blocks()[index];
    VoxelMask keep = block.mask;
    if (bricks != 0xff) {
        const VoxelMask in_bricks = brick_voxels(bricks);
        for (int w = 0; w < 8; ++w) keep[w] &= in_bricks[w];
    }
    if (voxels_) {
        const int before = count(keep);
        const uint8_t* lo = voxels_->lo.data() + index * VoxelBlock::kSize;
        const uint8_t* hi = voxels_->hi.data() + index * VoxelBlock::kSize;
        for (int w = 0; w < 8; ++w) {
            uint64_t bits = keep[w], kept = 0;
            while (bits) {
                const int bit = __builtin_ctzll(bits);
                bits &= bits - 1;
                const int offset = w * 64 + bit;
                if (int(hi[offset]) > transparent_up_to_[lo[offset]]) kept |= uint64_t(1) << bit;
            }
            keep[w] = kept;
        }
        out.voxels_culled = before - count(keep);
    }
    if (count(keep) == 0) {
        out.transparent = true;
        return out;
    }
    if (keep != block.mask) {
        mask = keep;
        out.splat = &mask;
    }
    return out;
}

}  // namespace pcvr
