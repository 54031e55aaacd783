/// @file block_voxels.h
/// @brief Walking the voxels of a VoxelBlock: which ones a splat visits, and where they are.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "pcvr/grid.h"
#include "pcvr/math.h"

namespace pcvr {

/// Calls fn(offset, value) for the active, finite, non-zero voxels of a block. Non-finite values
/// are skipped so that one bad voxel cannot poison the pixels of everything else in the image.
template <class Fn>
inline void for_each_voxel(const VoxelBlock& block, Fn&& fn) {
    for (int word = 0; word < 8; ++word) {
        uint64_t bits = block.mask[word];
        while (bits) {
            const int offset = word * 64 + __builtin_ctzll(bits);
            bits &= bits - 1;
            const float v = block.value(offset);
            if (v != 0.0f && std::isfinite(v)) fn(offset, v);
        }
    }
}

/// Index coordinates of a voxel given by its offset in the block (k fastest).
inline Vec3 voxel_position(const VoxelBlock& block, int offset) {
    return {double(block.origin[0] + (offset >> 6)), double(block.origin[1] + ((offset >> 3) & 7)),
            double(block.origin[2] + (offset & 7))};
}

/// Number of active voxels in the block.
inline int active_count(const VoxelBlock& block) {
    int n = 0;
    for (uint64_t w : block.mask) n += __builtin_popcountll(w);
    return n;
}

/// Every voxel of the block is active (most blocks of a CT scan or a dense simulation).
inline bool all_active(const VoxelBlock& block) {
    return std::all_of(block.mask.begin(), block.mask.end(), [](uint64_t w) { return w == ~uint64_t(0); });
}

}  // namespace pcvr
