/// @file block_value_ranges.cpp
/// @brief Building Grid::block_value_ranges (BlockValueRange): each block's and its bricks' value ranges
/// over the blocks around them, for transparency culling.
#include "volume/block_value_ranges.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "volume/block_lookup.h"

namespace pcvr {

namespace {

struct Range {
    float lo = std::numeric_limits<float>::infinity(), hi = -std::numeric_limits<float>::infinity();
    void include(float v) { lo = std::min(lo, v), hi = std::max(hi, v); }
    void include(const Range& r) { lo = std::min(lo, r.lo), hi = std::max(hi, r.hi); }
};

/// The bricks' reaches (in bricks) of BlockValueRange::brick_reach, brick_mid and brick_wide.
constexpr int kBrickReaches[3] = {2, 3, 4};
constexpr BlockValueRange::Bricks BlockValueRange::*kBrickRanges[3] = {&BlockValueRange::brick_reach, &BlockValueRange::brick_mid,
                                                                       &BlockValueRange::brick_wide};

/// BlockValueRange's brick ranges block by block: each block's neighbourhood of 5^3 blocks as 10^3
/// bricks (the ranges of their 4^3 halves), then for each of its own eight bricks the union over the
/// bricks within 2, 3 and 4 bricks (8, 12 and 16 index units: bricks lie on a grid of 4), one axis at a
/// time. For grids whose blocks fill too little of their bounding box for build_brick_ranges_densely.
void build_brick_ranges_block_by_block(const std::vector<VoxelBlock>& blocks, const std::vector<std::array<Range, 8>>& halves,
                        const BlockLookup& lookup, std::vector<BlockValueRange>& ranges) {
    constexpr int kSide = 10;  // bricks per side of the neighbourhood; the block's own are 4 and 5
    tbb::parallel_for(size_t(0), blocks.size(), [&](size_t b) {
        std::array<Range, kSide * kSide * kSide> local;
        const auto& o = blocks[b].origin;
        for (int dx = -2; dx <= 2; ++dx)
            for (int dy = -2; dy <= 2; ++dy)
                for (int dz = -2; dz <= 2; ++dz) {
                    const int64_t n = lookup.find({o[0] + dx * VoxelBlock::kDim, o[1] + dy * VoxelBlock::kDim, o[2] + dz * VoxelBlock::kDim});
                    if (n < 0) continue;
                    for (int h = 0; h < 8; ++h) {
                        const int x = 4 + 2 * dx + (h >> 2), y = 4 + 2 * dy + ((h >> 1) & 1), z = 4 + 2 * dz + (h & 1);
                        local[(x * kSide + y) * kSide + z] = halves[size_t(n)][h];
                    }
                }
        // Along x, then y, then z: unions over windows of 2 r + 1 bricks around the block's own 4 and 5.
        Range along_x[3][2][kSide][kSide], along_y[3][2][2][kSide];
        for (int r = 0; r < 3; ++r)
            for (int tx = 0; tx < 2; ++tx)
                for (int y = 0; y < kSide; ++y)
                    for (int z = 0; z < kSide; ++z) {
                        Range u;
                        for (int x = 4 + tx - kBrickReaches[r]; x <= 4 + tx + kBrickReaches[r]; ++x) u.include(local[(x * kSide + y) * kSide + z]);
                        along_x[r][tx][y][z] = u;
                    }
        for (int r = 0; r < 3; ++r)
            for (int tx = 0; tx < 2; ++tx)
                for (int ty = 0; ty < 2; ++ty)
                    for (int z = 0; z < kSide; ++z) {
                        Range u;
                        for (int y = 4 + ty - kBrickReaches[r]; y <= 4 + ty + kBrickReaches[r]; ++y) u.include(along_x[r][tx][y][z]);
                        along_y[r][tx][ty][z] = u;
                    }
        for (int r = 0; r < 3; ++r)
            for (int h = 0; h < 8; ++h) {
                const int tx = h >> 2, ty = (h >> 1) & 1, tz = h & 1;
                Range u;
                for (int z = 4 + tz - kBrickReaches[r]; z <= 4 + tz + kBrickReaches[r]; ++z) u.include(along_y[r][tx][ty][z]);
                (ranges[b].*kBrickRanges[r]).lo[h] = u.lo;
                (ranges[b].*kBrickRanges[r]).hi[h] = u.hi;
            }
    });
}

/// Each of `cells`' lines along `axis` (of a box `sides` cells, the last axis fastest) replaced by the unions
/// over windows of 2 `reach` + 1 cells around each cell, cut at the box's faces.
void unite_along(std::vector<Range>& cells, const std::array<int64_t, 3>& sides, int axis, int reach) {
    const int64_t stride = axis == 0 ? sides[1] * sides[2] : axis == 1 ? sides[2] : 1;
    const int64_t length = sides[axis];
    const int u = axis == 0 ? 1 : 0, v = axis == 2 ? 1 : 2;  // the other two axes
    tbb::parallel_for(tbb::blocked_range<int64_t>(0, sides[u] * sides[v]), [&](const tbb::blocked_range<int64_t>& lines) {
        std::vector<Range> line(static_cast<size_t>(length));
        for (int64_t l = lines.begin(); l < lines.end(); ++l) {
            std::array<int64_t, 3> at{0, 0, 0};
            at[u] = l / sides[v], at[v] = l % sides[v];
            const int64_t first = (at[0] * sides[1] + at[1]) * sides[2] + at[2];
            for (int64_t c = 0; c < length; ++c) line[size_t(c)] = cells[size_t(first + c * stride)];
            for (int64_t c = 0; c < length; ++c) {
                Range u_range;
                for (int64_t w = std::max<int64_t>(0, c - reach); w <= std::min(length - 1, c + reach); ++w) u_range.include(line[size_t(w)]);
                cells[size_t(first + c * stride)] = u_range;
            }
        }
    });
}

/// BlockValueRange's brick ranges over the blocks' bounding box at once: the halves laid out on a dense
/// lattice of bricks, then the windows' unions one axis at a time for each reach (in place: one lattice
/// of 8 ranges a block, 64 bytes). A tenth of the block-by-block work, which redoes each brick's unions
/// for every block whose neighbourhood holds it (the sum of a streamed CT's bricks' ranges took 3.8 s of 9).
void build_brick_ranges_densely(const std::vector<VoxelBlock>& blocks, const std::vector<std::array<Range, 8>>& halves,
                                const BlockLookup& lookup, std::vector<BlockValueRange>& ranges) {
    const std::array<int64_t, 3> first = lookup.first_block(), per_side = lookup.blocks_per_side();
    const std::array<int64_t, 3> sides{2 * per_side[0], 2 * per_side[1], 2 * per_side[2]};
    auto cell = [&](size_t b, int h) {
        const auto& o = blocks[b].origin;
        const int64_t x = 2 * (o[0] / VoxelBlock::kDim - first[0]) + (h >> 2), y = 2 * (o[1] / VoxelBlock::kDim - first[1]) + ((h >> 1) & 1),
                      z = 2 * (o[2] / VoxelBlock::kDim - first[2]) + (h & 1);
        return size_t((x * sides[1] + y) * sides[2] + z);
    };
    std::vector<Range> cells;
    for (int r = 0; r < 3; ++r) {
        cells.assign(size_t(sides[0] * sides[1] * sides[2]), Range{});
        tbb::parallel_for(size_t(0), blocks.size(), [&](size_t b) {
            for (int h = 0; h < 8; ++h) cells[cell(b, h)] = halves[b][h];
        });
        // x, then y, then z, as the block-by-block build: min and max are exact, so the order is free anyway.
        for (int axis = 0; axis < 3; ++axis) unite_along(cells, sides, axis, kBrickReaches[r]);
        tbb::parallel_for(size_t(0), blocks.size(), [&](size_t b) {
            for (int h = 0; h < 8; ++h) {
                (ranges[b].*kBrickRanges[r]).lo[h] = cells[cell(b, h)].lo;
                (ranges[b].*kBrickRanges[r]).hi[h] = cells[cell(b, h)].hi;
            }
        });
    }
}

/// Whether the ranges are built on dense lattices over the blocks' bounding box: where the blocks fill at
/// least half of it (as a brick of a stream, or a scan, does; the brick lattice is then at most 128 bytes
/// a block), else block by block.
bool builds_densely(const std::vector<VoxelBlock>& blocks, const BlockLookup& lookup) {
    const std::array<int64_t, 3> per_side = lookup.blocks_per_side();
    return lookup.dense() && uint64_t(per_side[0] * per_side[1] * per_side[2]) <= 2 * uint64_t(blocks.size());
}

/// The rings' ranges over the 3^3 and 5^3 blocks around each block (reach_, wide_), from its own
/// (min, max): block by block through `lookup`, or on a dense lattice of blocks one axis at a time.
void build_ring_ranges(const std::vector<VoxelBlock>& blocks, const BlockLookup& lookup, std::vector<BlockValueRange>& ranges) {
    if (builds_densely(blocks, lookup)) {
        const std::array<int64_t, 3> first = lookup.first_block(), sides = lookup.blocks_per_side();
        auto at = [&](size_t b) {
            const auto& o = blocks[b].origin;
            return size_t(((o[0] / VoxelBlock::kDim - first[0]) * sides[1] + (o[1] / VoxelBlock::kDim - first[1])) * sides[2] +
                          (o[2] / VoxelBlock::kDim - first[2]));
        };
        std::vector<Range> lattice(size_t(sides[0] * sides[1] * sides[2]));
        for (size_t b = 0; b < blocks.size(); ++b) lattice[at(b)] = Range{ranges[b].min, ranges[b].max};
        for (auto [lo, hi] : {std::pair{&BlockValueRange::reach_min, &BlockValueRange::reach_max},
                              std::pair{&BlockValueRange::wide_min, &BlockValueRange::wide_max}}) {
            for (int axis = 0; axis < 3; ++axis) unite_along(lattice, sides, axis, 1);  // each ring widens the last by a block
            for (size_t b = 0; b < blocks.size(); ++b) ranges[b].*lo = lattice[at(b)].lo, ranges[b].*hi = lattice[at(b)].hi;
        }
        return;
    }
    // Each ring is the union of the previous ring's ranges over the 27 blocks around.
    auto widen = [&](auto inner_lo, auto inner_hi, auto outer_lo, auto outer_hi) {
        tbb::parallel_for(size_t(0), blocks.size(), [&](size_t b) {
            float lo = ranges[b].*inner_lo, hi = ranges[b].*inner_hi;
            const auto& o = blocks[b].origin;
            for (int dx = -1; dx <= 1; ++dx)
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dz = -1; dz <= 1; ++dz) {
                        const int64_t n = lookup.find({o[0] + dx * VoxelBlock::kDim, o[1] + dy * VoxelBlock::kDim,
                                                       o[2] + dz * VoxelBlock::kDim});
                        if (n < 0) continue;
                        lo = std::min(lo, ranges[size_t(n)].*inner_lo);
                        hi = std::max(hi, ranges[size_t(n)].*inner_hi);
                    }
            ranges[b].*outer_lo = lo;
            ranges[b].*outer_hi = hi;
        });
    };
    widen(&BlockValueRange::min, &BlockValueRange::max, &BlockValueRange::reach_min, &BlockValueRange::reach_max);
    widen(&BlockValueRange::reach_min, &BlockValueRange::reach_max, &BlockValueRange::wide_min, &BlockValueRange::wide_max);
}

/// BlockValueRange's brick ranges (see builds_densely).
void build_brick_ranges(const std::vector<VoxelBlock>& blocks, const std::vector<std::array<Range, 8>>& halves,
                        const BlockLookup& lookup, std::vector<BlockValueRange>& ranges) {
    if (builds_densely(blocks, lookup))
        build_brick_ranges_densely(blocks, halves, lookup, ranges);
    else
        build_brick_ranges_block_by_block(blocks, halves, lookup, ranges);
}

}  // namespace

std::vector<BlockValueRange> build_block_value_ranges(const std::vector<VoxelBlock>& blocks) {
    std::vector<BlockValueRange> ranges(blocks.size());
    // The ranges of each block's eight 4^3 halves, (i >> 2, j >> 2, k >> 2) as bits 2, 1, 0.
    std::vector<std::array<Range, 8>> halves(blocks.size());
    tbb::parallel_for(size_t(0), blocks.size(), [&](size_t b) {
        const VoxelBlock& block = blocks[b];
        Range whole;
        for (int offset = 0; offset < VoxelBlock::kSize; ++offset) {
            const float v = block.value(offset);
            if (!block.active(offset) || !std::isfinite(v)) continue;  // the splats skip these too
            halves[b][((offset >> 8) & 1) << 2 | ((offset >> 5) & 1) << 1 | ((offset >> 2) & 1)].include(v);
            whole.include(v);
        }
        if (!(whole.lo <= whole.hi)) whole.lo = whole.hi = 0.0f;
        ranges[b].min = whole.lo;
        ranges[b].max = whole.hi;
    });
    // Every pass below looks up each block's neighbours: through the dense array where the grid allows it
    // (the hash map's 150 lookups a block were most of a streamed brick's range building).
    const BlockLookup lookup(blocks);
    build_ring_ranges(blocks, lookup, ranges);
    build_brick_ranges(blocks, halves, lookup, ranges);
    // Within 12: the 3^3 ring, and of the blocks two away along an axis only the half facing this one,
    // which is along each axis the bricks 3 before the block's first to 4 after: the union of its own
    // bricks' ranges within 12 (those over the ring's halves lie within the ring's range).
    tbb::parallel_for(size_t(0), blocks.size(), [&](size_t b) {
        Range within{ranges[b].reach_min, ranges[b].reach_max};
        for (int h = 0; h < 8; ++h) within.include(Range{ranges[b].brick_mid.lo[h], ranges[b].brick_mid.hi[h]});
        ranges[b].mid_min = within.lo;
        ranges[b].mid_max = within.hi;
    });
    return ranges;
}

}  // namespace pcvr
