// Grid::block_value_ranges' builder against each range's definition found voxel by voxel: the blocks laid
// out densely (the lattice build) and spread apart (block by block).
#include <cmath>
#include <vector>

#include "random_blocks.h"
#include "unit_test.h"
#include "volume/block_value_ranges.h"

using namespace pcvr;

namespace {

struct Bounds {
    float lo = INFINITY, hi = -INFINITY;
    bool operator==(const Bounds& o) const { return lo == o.lo && hi == o.hi; }
};

/// The active, finite values of `blocks` at indices in [lo, hi] on every axis.
Bounds values_in(const std::vector<VoxelBlock>& blocks, const std::array<int, 3>& lo, const std::array<int, 3>& hi) {
    Bounds r;
    for (const VoxelBlock& b : blocks)
        for (int offset = 0; offset < VoxelBlock::kSize; ++offset) {
            const int i = b.origin[0] + (offset >> 6), j = b.origin[1] + ((offset >> 3) & 7), k = b.origin[2] + (offset & 7);
            const float v = b.value(offset);
            if (!b.active(offset) || !std::isfinite(v)) continue;
            if (i < lo[0] || j < lo[1] || k < lo[2] || i > hi[0] || j > hi[1] || k > hi[2]) continue;
            r.lo = std::min(r.lo, v), r.hi = std::max(r.hi, v);
        }
    return r;
}

/// A block's own range: 0 to 0 where it has no active, finite voxel.
Bounds own(const VoxelBlock& b) {
    Bounds r = values_in({b}, {b.origin[0], b.origin[1], b.origin[2]}, {b.origin[0] + 7, b.origin[1] + 7, b.origin[2] + 7});
    return r.lo <= r.hi ? r : Bounds{0.0f, 0.0f};
}

/// The union of the own ranges of the blocks within `blocks_away` blocks of `b` (Chebyshev).
Bounds around(const std::vector<VoxelBlock>& blocks, const VoxelBlock& b, int blocks_away) {
    Bounds r;
    for (const VoxelBlock& n : blocks) {
        bool near = true;
        for (int a = 0; a < 3; ++a) near = near && std::abs(n.origin[a] - b.origin[a]) <= 8 * blocks_away;
        if (!near) continue;
        const Bounds o = own(n);
        r.lo = std::min(r.lo, o.lo), r.hi = std::max(r.hi, o.hi);
    }
    return r;
}

/// Mismatches between build_block_value_ranges and the definitions (grid.h's BlockValueRange).
int mismatches(const std::vector<VoxelBlock>& blocks) {
    const std::vector<BlockValueRange> ranges = build_block_value_ranges(blocks);
    int wrong = 0;
    for (size_t b = 0; b < blocks.size(); ++b) {
        const VoxelBlock& block = blocks[b];
        const auto& o = block.origin;
        const BlockValueRange& r = ranges[b];
        wrong += !(Bounds{r.min, r.max} == own(block));
        wrong += !(Bounds{r.reach_min, r.reach_max} == around(blocks, block, 1));
        wrong += !(Bounds{r.wide_min, r.wide_max} == around(blocks, block, 2));
        // Within 12 index units: the 3^3 blocks' ranges and every voxel 12 beyond the block's faces.
        Bounds mid = around(blocks, block, 1);
        const Bounds near = values_in(blocks, {o[0] - 12, o[1] - 12, o[2] - 12}, {o[0] + 19, o[1] + 19, o[2] + 19});
        mid.lo = std::min(mid.lo, near.lo), mid.hi = std::max(mid.hi, near.hi);
        wrong += !(Bounds{r.mid_min, r.mid_max} == mid);
        const BlockValueRange::Bricks* bricks[3] = {&r.brick_reach, &r.brick_mid, &r.brick_wide};
        for (int reach = 0; reach < 3; ++reach)
            for (int h = 0; h < 8; ++h) {
                const int d = 8 + 4 * reach;  // 8, 12, 16 index units
                const std::array<int, 3> first{o[0] + 4 * (h >> 2), o[1] + 4 * ((h >> 1) & 1), o[2] + 4 * (h & 1)};
                const Bounds want = values_in(blocks, {first[0] - d, first[1] - d, first[2] - d}, {first[0] + 3 + d, first[1] + 3 + d, first[2] + 3 + d});
                wrong += !(Bounds{bricks[reach]->lo[h], bricks[reach]->hi[h]} == want);
            }
    }
    return wrong;
}

}  // namespace

TEST(block_value_ranges_match_their_definitions_on_a_dense_lattice) {
    const RandomBlocks data;  // 11 blocks of a 3 x 2 x 2 box: built on the dense lattice
    CHECK(mismatches(data.blocks) == 0);
}

TEST(block_value_ranges_match_their_definitions_block_by_block) {
    RandomBlocks data;
    // Blocks spread over a box eight times their number: built block by block; pairs still neighbours.
    for (size_t b = 0; b < data.blocks.size(); ++b)
        if (b % 3 == 0) data.blocks[b].origin[2] += 64;
    CHECK(mismatches(data.blocks) == 0);
}
