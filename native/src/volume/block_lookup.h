/// @file block_lookup.h
/// @brief Finding a grid's blocks by origin: what the neighbourhood ranges (BlockValueRange,
/// VoxelValueRanges) read around each block.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "pcvr/grid.h"

namespace pcvr {

struct OriginHash {
    size_t operator()(const std::array<int32_t, 3>& o) const {
        return std::hash<uint64_t>()((uint64_t(uint32_t(o[0])) * 0x9E3779B1u) ^ (uint64_t(uint32_t(o[1])) << 21) ^
                                     (uint64_t(uint32_t(o[2])) << 42));
    }
};
using BlockIndex = std::unordered_map<std::array<int32_t, 3>, size_t, OriginHash>;

/// Block neighbours by origin: a dense array over the blocks' bounding box where that is small (a
/// lookup per neighbour, 125 per block, was most of the brick ranges' cost through the hash map).
class BlockLookup {
public:
    /// Builds the hash map only where the dense array would be too large (hashing every block cost a
    /// streamed brick's range building as much as its lookups).
    explicit BlockLookup(const std::vector<VoxelBlock>& blocks) {
        if (blocks.empty()) return;
        for (int a = 0; a < 3; ++a) lo_[a] = hi_[a] = blocks[0].origin[a] / VoxelBlock::kDim;
        for (const VoxelBlock& b : blocks)
            for (int a = 0; a < 3; ++a) {
                lo_[a] = std::min(lo_[a], int64_t(b.origin[a] / VoxelBlock::kDim));
                hi_[a] = std::max(hi_[a], int64_t(b.origin[a] / VoxelBlock::kDim));
            }
        for (int a = 0; a < 3; ++a) size_[a] = hi_[a] - lo_[a] + 1;
        if (size_[0] * size_[1] * size_[2] > (int64_t(1) << 24)) {
            index_.reserve(blocks.size());
            for (size_t b = 0; b < blocks.size(); ++b) index_.emplace(blocks[b].origin, b);
            return;
        }
        dense_.assign(size_t(size_[0] * size_[1] * size_[2]), -1);
        for (size_t b = 0; b < blocks.size(); ++b) dense_[cell(blocks[b].origin)] = int64_t(b);
    }
    /// Whether lookups go through the dense array; then the blocks' bounding box, in blocks, is
    /// first_block() + [0, blocks_per_side()).
    bool dense() const { return !dense_.empty(); }
    std::array<int64_t, 3> first_block() const { return {lo_[0], lo_[1], lo_[2]}; }
    std::array<int64_t, 3> blocks_per_side() const { return {size_[0], size_[1], size_[2]}; }
    /// The block at `origin` (a multiple of 8), or -1.
    int64_t find(const std::array<int32_t, 3>& origin) const {
        if (dense_.empty()) {
            const auto it = index_.find(origin);
            return it == index_.end() ? -1 : int64_t(it->second);
        }
        for (int a = 0; a < 3; ++a) {
            const int64_t c = origin[a] / VoxelBlock::kDim;
            if (c < lo_[a] || c > hi_[a]) return -1;
        }
        return dense_[cell(origin)];
    }

private:
    size_t cell(const std::array<int32_t, 3>& o) const {
        return size_t(((o[0] / VoxelBlock::kDim - lo_[0]) * size_[1] + (o[1] / VoxelBlock::kDim - lo_[1])) * size_[2] +
                      (o[2] / VoxelBlock::kDim - lo_[2]));
    }
    BlockIndex index_;  ///< only where not dense
    int64_t lo_[3] = {0, 0, 0}, hi_[3] = {0, 0, 0}, size_[3] = {0, 0, 0};
    std::vector<int64_t> dense_;
};

}  // namespace pcvr
