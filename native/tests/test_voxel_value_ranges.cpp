// Grid::voxel_value_ranges' builder against the box's least and largest value found voxel by voxel.
#include <cmath>
#include <map>
#include <random>
#include <vector>

#include "pcvr/errors.h"
#include "unit_test.h"
#include "volume/voxel_value_ranges.h"

using namespace pcvr;

namespace {

/// Blocks on a 3 x 2 x 2 lattice with one gap, random values, some voxels inactive and one NaN; and a
/// constant block (an active tile's chunk).
struct Blocks {
    std::vector<VoxelBlock> blocks;
    std::vector<std::vector<float>> values;
    float background = -5.0f;

    Blocks() {
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

}  // namespace

TEST(voxel_value_ranges_hold_each_box_within_a_level) {
    const Blocks data;
    for (int radius : {1, 3, 9}) {
        const VoxelValueRanges r = build_voxel_value_ranges(data.blocks, data.background, radius);
        CHECK(r.radius == radius);
        CHECK(r.lo.size() == data.blocks.size() * VoxelBlock::kSize);
        int mismatches = 0;
        for (size_t b = 0; b < data.blocks.size(); ++b)
            for (int offset = 0; offset < VoxelBlock::kSize; ++offset) {
                const auto& o = data.blocks[b].origin;
                const int i = o[0] + (offset >> 6), j = o[1] + ((offset >> 3) & 7), k = o[2] + (offset & 7);
                float lo = INFINITY, hi = -INFINITY;
                for (int di = -radius; di <= radius; ++di)
                    for (int dj = -radius; dj <= radius; ++dj)
                        for (int dk = -radius; dk <= radius; ++dk) {
                            const float v = data.at(i + di, j + dj, k + dk);
                            lo = std::min(lo, v), hi = std::max(hi, v);
                        }
                const double low = r.value(r.lo[b * VoxelBlock::kSize + offset]), high = r.value(r.hi[b * VoxelBlock::kSize + offset]);
                // Rounded outwards, by less than a level.
                mismatches += !(low <= lo && lo - low < r.step && high >= hi && high - hi < r.step);
            }
        CHECK(mismatches == 0);
    }
}

TEST(voxel_value_ranges_refuse_radii_they_do_not_build) {
    const Blocks data;
    for (int radius : {0, VoxelValueRanges::kMostRadius + 1}) {
        bool refused = false;
        try {
            build_voxel_value_ranges(data.blocks, data.background, radius);
        } catch (const InvalidArgument&) {
            refused = true;
        }
        CHECK(refused);
    }
}
