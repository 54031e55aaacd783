/// @file random_blocks.h
/// @brief Test blocks with random values: what the builders of per-voxel tables are checked against.
#pragma once

#include <cmath>
#include <random>
#include <vector>

#include "pcvr/grid.h"

namespace pcvr {

/// Blocks on a 3 x 2 x 2 lattice with one gap, random values, some voxels inactive and one NaN; and a
/// constant block (an active tile's chunk).
struct RandomBlocks {
    std::vector<VoxelBlock> blocks;
    std::vector<std::vector<float>> values;
    float background = -5.0f;

    RandomBlocks() {
        std::mt19937 random(7);
        std::uniform_real_distribution<float> value(-20.0f, 30.0f);
        values.reserve(16);
        for (int x = 0; x < 3; ++x)
            for (int y = 0; y < 2; ++y)
                for (int z = 0; z < 2; ++z) {
                    if (x == 1 && y == 1 && z == 0) continue;  // the gap: background
                    VoxelBlock b;
                    b.origin = {x * 8 - 8, y * 8, z * 8};
                    if (x == 2 && y == 0 && z == 1) {
                        b.constant = 12.5f;
                        b.mask.fill(~uint64_t(0));
                    } else {
                        values.emplace_back(VoxelBlock::kSize);
                        for (float& v : values.back()) v = value(random);
                        b.values = values.back().data();
                        for (int offset = 0; offset < VoxelBlock::kSize; ++offset)
                            if (random() % 5) b.mask[offset >> 6] |= uint64_t(1) << (offset & 63);
                    }
                    blocks.push_back(b);
                }
        values[0][77] = NAN;
    }

    /// The value at index (i, j, k) as the ranges count it.
    float at(int i, int j, int k) const {
        for (const VoxelBlock& b : blocks) {
            const int x = i - b.origin[0], y = j - b.origin[1], z = k - b.origin[2];
            if (x < 0 || y < 0 || z < 0 || x >= 8 || y >= 8 || z >= 8) continue;
            const int offset = (x << 6) | (y << 3) | z;
            const float v = b.value(offset);
            return b.active(offset) && std::isfinite(v) ? v : background;
        }
        return background;
    }
};

}  // namespace pcvr
